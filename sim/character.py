"""Characters: a skinned mesh with a skeleton and clips, or a keyframe animation."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim.mesh import Mesh
from sim.skeleton import Skeleton
from sim.keyframes import KeyframeAnimation


@dataclass
class SkinnedCharacter:
    """A linear-blend-skinned mesh driven by named clips.

    clips : dict name -> sim.clip.Clip (insertion order is the clip index used
        in CrowdState.clip).
    """

    name: str
    mesh: Mesh
    skeleton: Skeleton
    clips: dict = field(default_factory=dict)
    source: str = ""

    kind = "skinned"

    def clip_names(self) -> list[str]:
        return list(self.clips)


@dataclass
class KeyframedCharacter:
    """A keyframe animation (Wand & Straßer §3); ``animations`` maps clip name
    to KeyframeAnimation (e.g. one per glTF morph animation)."""

    name: str
    animations: dict = field(default_factory=dict)
    source: str = ""

    kind = "keyframed"

    def clip_names(self) -> list[str]:
        return list(self.animations)


Character = SkinnedCharacter | KeyframedCharacter
