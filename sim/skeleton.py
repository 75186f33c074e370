"""Joint hierarchies and pose evaluation (forward kinematics).

Quaternions are stored (x, y, z, w) as in glTF. Matrices are 4x4, column
vectors (p' = M @ p), float64 on the CPU.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim import math3d


@dataclass
class Skeleton:
    """A joint hierarchy with a rest pose and inverse bind matrices.

    Attributes
    ----------
    names : list[str], length J
    parents : (J,) int32
        Parent joint index, -1 for roots. Joints are topologically ordered:
        ``parents[j] < j`` for every non-root j.
    rest_translation : (J, 3) float64, local to the parent
    rest_rotation : (J, 4) float64, unit quaternions (x, y, z, w), local
    rest_scale : (J, 3) float64, local
    inverse_bind : (J, 4, 4) float64
        Maps mesh (bind) space into each joint's space at bind time.
    root_transform : (4, 4) float64
        Transform of the skeleton's parent node(s) (glTF scene graph above the
        roots); applied to every root.
    """

    names: list
    parents: np.ndarray
    rest_translation: np.ndarray
    rest_rotation: np.ndarray
    rest_scale: np.ndarray
    inverse_bind: np.ndarray
    root_transform: np.ndarray | None = None

    @property
    def n_joints(self) -> int:
        return int(self.parents.shape[0])

    def _root(self) -> np.ndarray:
        if self.root_transform is None:
            return np.eye(4)
        return np.asarray(self.root_transform, np.float64)

    def global_matrices(self, translation: np.ndarray, rotation: np.ndarray, scale: np.ndarray) -> np.ndarray:
        """Forward kinematics: local TRS -> global joint matrices.

        Parameters
        ----------
        translation : (..., J, 3) float
        rotation : (..., J, 4) float, quaternions (x, y, z, w); normalised here
        scale : (..., J, 3) float
            Leading axes (e.g. a batch of times) are optional and broadcast.

        Returns
        -------
        (..., J, 4, 4) float64
            ``G[j] = G[parent[j]] @ TRS_j``, roots get ``root_transform @ TRS_j``.
            Joints are topologically ordered (``parents[j] < j``), so one pass
            in index order suffices.
        """
        local = math3d.trs_matrix(translation, rotation, scale)
        if local.shape[-3] != self.n_joints:
            raise ValueError(f"Skeleton.global_matrices: expected {self.n_joints} joints, got {local.shape[-3]}")
        parents = np.asarray(self.parents)
        bad = np.nonzero(parents >= np.arange(parents.shape[0]))[0]
        if bad.size:
            j = int(bad[0])
            raise ValueError(f"Skeleton: joint {j} ({self.names[j] if j < len(self.names) else j!r}) has parent "
                             f"{int(parents[j])}; joints must be topologically ordered (parent < index, -1 for roots)")
        out = np.empty_like(local)
        root = self._root()
        for j in range(self.n_joints):
            p = int(parents[j])
            parent = root if p < 0 else out[..., p, :, :]
            out[..., j, :, :] = parent @ local[..., j, :, :]
        return out

    def skinning_matrices(self, translation: np.ndarray, rotation: np.ndarray, scale: np.ndarray) -> np.ndarray:
        """``global_matrices(...) @ inverse_bind``: (..., J, 4, 4) float64.

        A mesh-space (bind) vertex ``p`` bound to joint j moves to
        ``S[j] @ p``; at the rest pose ``S[j]`` is the identity when
        ``inverse_bind`` matches the rest pose.
        """
        return self.global_matrices(translation, rotation, scale) @ np.asarray(self.inverse_bind, np.float64)

    def rest_global_matrices(self) -> np.ndarray:
        """Global joint matrices at the rest pose, (J, 4, 4) float64."""
        return self.global_matrices(*self.rest_pose())

    def rest_inverse_bind(self) -> np.ndarray:
        """Inverse bind matrices consistent with the rest pose, (J, 4, 4) float64."""
        return math3d.invert_affine(self.rest_global_matrices())

    def joint_positions(self, translation=None, rotation=None, scale=None) -> np.ndarray:
        """World positions (..., J, 3) float64 of the joints (rest pose by default)."""
        if translation is None:
            translation, rotation, scale = self.rest_pose()
        return self.global_matrices(translation, rotation, scale)[..., :3, 3]

    def index(self, name: str) -> int:
        """Index of the joint called ``name``; KeyError names the skeleton's joints."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no joint {name!r}; joints are: {', '.join(self.names)}") from None

    def rest_pose(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Local rest TRS as arrays (copies)."""
        return self.rest_translation.copy(), self.rest_rotation.copy(), self.rest_scale.copy()
