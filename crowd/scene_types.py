"""The validated scene (:func:`crowd.scene.load_scene` builds it): plain frozen dataclasses, no parsing.

The parser (:mod:`crowd.scene`) and its split modules (:mod:`crowd.scene_props`, :mod:`crowd.scene_routing`,
:mod:`crowd.scene_journeys`) all build these, so they live below all of them; ``crowd.scene`` re-exports them.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import render.world.light as _light
import lod.raster_route as _raster


@dataclass(frozen=True)
class CharacterSpec:
    """One ``[[characters]]`` entry; exactly one of ``generator`` / ``file`` is set.

    file : absolute Path of the glTF file, or None
    triangles : int target triangle count (generator only), else None
    """

    name: str
    generator: str | None
    file: Path | None
    triangles: int | None
    seed: int
    scale: float
    fps: int
    variation: tuple | None = None  # ((key, value), ...) of VARIATION_SCHEMA, or None: no colour variation
    radius: float | None = None  # body radius at scale 1 (avoidance); None = the character's footprint
    dance: float = 0.0  # seconds of a generated "dance" clip (sim.dance), generator only; 0 = none

    def spec(self) -> str:
        """Short human-readable source, e.g. ``generator:humanoid:5000`` or the file path."""
        return f"generator:{self.generator}:{self.triangles}" if self.generator else str(self.file)


@dataclass(frozen=True)
class PlacementSpec:
    """One ``[[placement]]`` group.

    character : int, index into Scene.characters
    clip : str or None (None: the character's first clip)
    params : dict validated against ``sim.placement.PLACEMENTS[kind][0]``
    """

    kind: str
    character: int
    clip: str | None
    params: dict
    index: int = 0


@dataclass(frozen=True)
class EffectSpec:
    """One listed effect with its parameters validated against the module's PARAMS."""

    name: str
    params: dict
    index: int = 0


@dataclass(frozen=True)
class CameraKey:
    time: float
    position: tuple
    target: tuple


@dataclass(frozen=True)
class CameraSpec:
    """Fixed camera (``keys`` empty) or a keyed path (``keys`` sorted by time).

    position, target : (3,) tuples of float (fixed camera)
    keys : tuple of CameraKey; from ``keys`` or ``path_file`` (absolute Path)
    """

    fov: float
    near: float
    far: float
    position: tuple
    target: tuple
    keys: tuple = ()
    path_file: Path | None = None


@dataclass(frozen=True)
class RenderSpec:
    size: tuple
    background: tuple
    png_every: int
    ground: bool = True
    light: object = _light.Light()  # render.world.light.Light
    shadows: str = _light.DEFAULT_SHADOWS
    shadow_distance: float = 60.0
    shadow_map_size: int = 2048
    raster_threshold: float = _raster.DEFAULT_THRESHOLD


@dataclass(frozen=True)
class Scene:
    """A validated scene; every path is absolute.

    path : Path of the scene file
    output_dir : Path where a run writes (atomically)
    terrain : dict of validated ``sim.terrain.PARAMS`` or None
    """

    path: Path
    name: str
    seed: int
    dt: float
    substeps: int
    frames: int
    characters: tuple
    placements: tuple
    effects: tuple
    camera: CameraSpec
    render: RenderSpec
    lod_mode: str
    output_dir: Path
    terrain: dict | None = None
    lod_params: tuple = ()  # ((key, value), ...) of the [lod] table besides mode (lod.modes PARAMS)
    terrain_lod: tuple = ()  # ((key, value), ...): the [terrain] table's view-dependent LOD keys (lod.temporal.terrain_keyframes)
    lod_common: tuple = ()  # ((key, value), ...): the [lod] keys of every mode (lod.temporal.selection)
    props: tuple = ()  # PropSpec of every [[props]] table
    trajectories: bool = False  # [output] trajectories: write trajectories.txt (crowd.trajectories)
    measurements: tuple = ()  # crowd.measurement.MeasurementSpec of the [[measurement]] tables
    video: bool = False  # [output] video: write video.mp4 (crowd.video)

    @property
    def effect_names(self) -> list:
        return [e.name for e in self.effects]

    def with_overrides(self, frames: int | None = None, size: tuple | None = None, out: str | Path | None = None,
                       png_every: int | None = None, video: bool | None = None) -> "Scene":
        """A copy with command-line overrides applied (values already validated by the caller)."""
        s = self
        if frames is not None:
            s = dataclasses.replace(s, frames=int(frames))
        if size is not None or png_every is not None:
            r = s.render
            s = dataclasses.replace(s, render=dataclasses.replace(
                r, size=tuple(size) if size is not None else r.size,
                png_every=int(png_every) if png_every is not None else r.png_every))
        if out is not None:
            s = dataclasses.replace(s, output_dir=Path(out).absolute())
        if video is not None:
            s = dataclasses.replace(s, video=bool(video))
        return s
