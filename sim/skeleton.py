"""Joint hierarchies and pose evaluation (forward kinematics).

Quaternions are stored (x, y, z, w) as in glTF. Matrices are 4x4, column
vectors (p' = M @ p), float64 on the CPU.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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

    def global_matrices(self, translation: np.ndarray, rotation: np.ndarray, scale: np.ndarray) -> np.ndarray:
        """Forward kinematics: local TRS (J,3)/(J,4)/(J,3) -> global (J,4,4) float64."""
        raise NotImplementedError

    def skinning_matrices(self, translation: np.ndarray, rotation: np.ndarray, scale: np.ndarray) -> np.ndarray:
        """global_matrices(...) @ inverse_bind, (J,4,4) float64."""
        raise NotImplementedError

    def rest_pose(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Local rest TRS as arrays (copies)."""
        return self.rest_translation.copy(), self.rest_rotation.copy(), self.rest_scale.copy()
