"""Characters: a skinned mesh with a skeleton and clips, or a keyframe animation."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim.keyframes import KeyframeAnimation
from sim.mesh import Mesh
from sim.skeleton import Skeleton


@dataclass
class SkinnedCharacter:
    """A linear-blend-skinned mesh driven by named clips.

    clips : dict name -> sim.clip.Clip (insertion order is the clip index used
        in CrowdState.clip).
    notes : list of str, what the importer repaired or made up (one sentence each, e.g. weights normalised,
        a rest clip added); ``crowd info`` prints them.
    regions : dict name -> (V,) bool, named parts of the mesh (e.g. a generated humanoid's "shirt");
        the scene's colour variation can be limited to some of them.
    """

    name: str
    mesh: Mesh
    skeleton: Skeleton
    clips: dict = field(default_factory=dict)
    source: str = ""
    notes: list = field(default_factory=list)
    regions: dict = field(default_factory=dict)

    kind = "skinned"

    def clip_names(self) -> list[str]:
        return list(self.clips)

    def clip(self, which):
        """The clip with index or name ``which`` (KeyError/IndexError name the choices)."""
        return self.clips[_clip_key(self.name, list(self.clips), which)]

    def clip_index(self, name: str) -> int:
        """Index (CrowdState.clip) of the clip called ``name``."""
        return list(self.clips).index(_clip_key(self.name, list(self.clips), name))

    def duration(self, which) -> float:
        """Duration in seconds of clip ``which`` (index or name)."""
        return float(self.clip(which).duration)

    def rest_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounds (lo (3,), hi (3,)) float64 of the rest-pose mesh."""
        return _bounds(self.mesh.positions)


@dataclass
class KeyframedCharacter:
    """A keyframe animation (Wand & Straßer §3); ``animations`` maps clip name
    to KeyframeAnimation (e.g. one per glTF morph animation); ``notes`` as for :class:`SkinnedCharacter`."""

    name: str
    animations: dict = field(default_factory=dict)
    source: str = ""
    notes: list = field(default_factory=list)

    kind = "keyframed"

    def clip_names(self) -> list[str]:
        return list(self.animations)

    def clip(self, which):
        """The KeyframeAnimation with index or name ``which``."""
        return self.animations[_clip_key(self.name, list(self.animations), which)]

    def clip_index(self, name: str) -> int:
        return list(self.animations).index(_clip_key(self.name, list(self.animations), name))

    def duration(self, which) -> float:
        return float(self.clip(which).duration)

    def rest_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds (lo (3,), hi (3,)) float64 of the first keyframe of the first animation."""
        anim = next(iter(self.animations.values()))
        return _bounds(anim.keyframes[0].positions)


def _clip_key(char_name: str, names: list, which) -> str:
    if isinstance(which, (int, np.integer)) and not isinstance(which, bool):
        if not 0 <= int(which) < len(names):
            raise IndexError(f"character {char_name!r}: clip index {int(which)} outside 0..{len(names) - 1}")
        return names[int(which)]
    if which not in names:
        raise KeyError(f"character {char_name!r} has no clip {which!r}; clips: {', '.join(map(str, names)) or 'none'}")
    return which


def _bounds(positions) -> tuple[np.ndarray, np.ndarray]:
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    if p.shape[0] == 0:
        return np.zeros(3), np.zeros(3)
    return p.min(0), p.max(0)


Character = SkinnedCharacter | KeyframedCharacter
