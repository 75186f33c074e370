"""Scene files (``scenes/*.toml``): load, validate in full, resolve paths.

The format is specified in ``docs/scenes.md``; this module is its only
implementation. :func:`load_scene` checks the *whole* document before anything
is built: every key, type and range, every cross reference (placements name a
character, effects name a registered effect) and every referenced file. Any
problem is a :class:`crowd.errors.SceneError` whose message is one line
``FILE: KEY: message`` naming what would be accepted.

Effect and placement parameters are validated against the schemas that their
own modules declare (``PARAMS`` of an effect module, ``sim.placement.PLACEMENTS``,
``sim.terrain.PARAMS``) with :func:`sim.params.validate`. Reading an effect's
``PARAMS`` imports its module, but nothing is constructed or installed here;
modules of effects a scene does not list are never imported.
"""
from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path
from typing import Any

import render.world.light as _light
import lod.raster_route as _raster
from crowd.errors import SceneError
from crowd.scene_types import (CameraKey, CameraSpec, CharacterSpec, EffectSpec, PlacementSpec, RenderSpec,
                               Scene)
from crowd.scene_props import PropSpec, parse_props  # noqa: F401 (PropSpec re-exported)
from crowd.scene_variation import DEFAULT_VARIATION, VARIATION_SCHEMA, parse_variation  # noqa: F401
from lod.modes import mode_names as _mode_names
from lod.modes import mode_params as _mode_params
from sim.params import Param, ParamError, validate

#: character generators accepted by ``[[characters]] generator``
GENERATORS = ("humanoid", "quadruped")
#: glTF file suffixes accepted by ``[[characters]] file``
GLTF_SUFFIXES = (".glb", ".gltf")
#: level-of-detail modes accepted by ``[lod] mode`` (the registry in lod/modes.py)
LOD_MODES = _mode_names()
#: keys every ``[[placement]]`` table has, whatever its kind
PLACEMENT_COMMON = ("kind", "character", "clip")
#: keys accepted at the top level of a scene document
TOP_LEVEL_KEYS = ("name", "seed", "dt", "substeps", "frames", "effects", "characters", "placement",
                  "props", "terrain", "camera", "render", "lod", "output", "measurement", "stages", "journeys",
                  "sources")

TOP_SCHEMA = {
    "name": Param("str", None, doc="scene name; default: file stem"),
    "seed": Param("int", 0, min=0, doc="root of all randomness"),
    "dt": Param("float", 1.0 / 30.0, doc="fixed simulation step, seconds, 0 < dt <= 1"),
    "substeps": Param("int", 1, min=1, max=1000, doc="sub-steps per frame"),
    "frames": Param("int", 120, min=1, doc="frames to run"),
}

CHARACTER_SCHEMA = {
    "name": Param("str", doc="unique id used by placements"),
    "generator": Param("str", None, choices=GENERATORS),
    "file": Param("str", None, doc="glTF 2.0 file, relative to the scene file"),
    "triangles": Param("int", None, min=500, max=200000, doc="generator only"),
    "seed": Param("int", None, min=0, doc="generator seed; default: scene seed"),
    "scale": Param("float", 1.0, doc="uniform scale, > 0"),
    "fps": Param("int", 30, min=1, max=240, doc="clip baking rate"),
    "variation": Param("table", None, doc="per-agent colour variation (VARIATION_SCHEMA), or false; "
                       "default: DEFAULT_VARIATION for generated humanoids, none otherwise"),
    "radius": Param("float", None, min=0.001, max=100.0,
                    doc="body radius at scale 1, metres (effect avoidance); default: the footprint"),
    "dance": Param("float", 0.0, min=0.0, max=600.0,
                   doc="generator only: seconds of an extra looping clip \"dance\" (sim.dance); 0 = none"),
}
#: default ``triangles`` of a generated character
DEFAULT_TRIANGLES = 5000

CAMERA_SCHEMA = {
    "fov": Param("float", 50.0, min=1.0, max=179.0, doc="vertical field of view, degrees"),
    "near": Param("float", 0.1, doc="near plane, metres, > 0"),
    "far": Param("float", 1000.0, doc="far plane, metres, > near"),
    "position": Param("vec3", None),
    "target": Param("vec3", None),
    "keys": Param("list", None, doc="keyed poses {time, position, target}"),
    "path_file": Param("str", None, doc="JSON camera path, relative to the scene file"),
}
CAMERA_KEY_SCHEMA = {
    "time": Param("float", min=0.0),
    "position": Param("vec3"),
    "target": Param("vec3"),
}
DEFAULT_CAMERA_POSITION = (0.0, 5.0, 20.0)
DEFAULT_CAMERA_TARGET = (0.0, 1.0, 0.0)

LIGHT_SCHEMA = {
    "light_dir": Param("vec3", list(_light.DEFAULT_DIRECTION), doc="direction towards the light, non-zero"),
    "light_color": Param("vec3", list(_light.DEFAULT_COLOR), doc="linear RGB of the direct light"),
    "ambient": Param("float", _light.DEFAULT_AMBIENT, min=0.0, max=_light.MAX_INTENSITY, doc="ambient factor"),
    "shadows": Param("str", _light.DEFAULT_SHADOWS, choices=_light.SHADOW_MODES,
                     doc="blob decals, shadow map or none"),
    "shadow_distance": Param("float", 60.0, min=0.1, doc="metres from the camera within which agents cast (map)"),
    "shadow_map_size": Param("int", 2048, min=16, max=8192, doc="side of the shadow map, texels"),
}
RENDER_SCHEMA = {
    "size": Param("list", [1280, 720], doc="[width, height] pixels, each 16 ..= 8192"),
    "background": Param("vec3", [0.1, 0.1, 0.12], doc="linear RGB in [0, 1]"),
    "png_every": Param("int", 0, min=0, doc="write every k-th frame as PNG; 0 = none"),
    "ground": Param("bool", True, doc="draw the ground plane and its grid (not with [terrain]: it is the ground)"),
    "raster_threshold": Param("float", _raster.DEFAULT_THRESHOLD, min=0.0, max=_raster.MAX_THRESHOLD,
                              doc="pixels: copies whose triangles are at most this large on screen are "
                                  "rasterised in compute (render/raster/); 0 = the hardware path only"),
    **LIGHT_SCHEMA,  # the directional light and the shadows (render.light, render.shadows)
}
SIZE_RANGE = (16, 8192)

LOD_SCHEMA = {"mode": Param("str", "none", choices=LOD_MODES)}
OUTPUT_SCHEMA = {"dir": Param("str", None, doc="relative to the working directory; default out/<name>"),
                 "trajectories": Param("bool", False, doc="write trajectories.txt (PedPy's text format; "
                                       "crowd.trajectories) with the run's outputs"),
                 "video": Param("bool", False, doc="write the run as video.mp4 (H.264, every frame)")}


# ---------------------------------------------------------------------------------------------------------------------
# loading
# ---------------------------------------------------------------------------------------------------------------------

_TOML_POS = re.compile(r"^(?P<msg>.*?)\s*\(at line (?P<line>\d+), column (?P<col>\d+)\)\s*$")


def load_scene(path: str | Path) -> Scene:
    """Read, validate and resolve a scene file.

    Parameters
    ----------
    path : str or Path of a TOML scene file

    Returns
    -------
    Scene

    Raises
    ------
    crowd.errors.SceneError
        Any problem with the file, one line naming the key and the accepted values.
    """
    path = Path(path)
    shown = str(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise SceneError(shown, "", "scene file not found") from None
    except IsADirectoryError:
        raise SceneError(shown, "", "is a directory, expected a TOML scene file") from None
    except UnicodeDecodeError as e:
        raise SceneError(shown, "", f"not UTF-8 text ({e.reason} at byte {e.start})") from None
    except OSError as e:
        raise SceneError(shown, "", f"cannot read: {e.strerror}") from None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        m = _TOML_POS.match(str(e))
        if m:
            raise SceneError(shown, f"line {m['line']}, column {m['col']}",
                             f"TOML syntax error: {m['msg']}") from None
        raise SceneError(shown, "", f"TOML syntax error: {e}") from None
    return parse_scene(doc, path)


#: keys of [[placement]] and [[effects]] tables that name a data file (a recording, a floor plan)
DATA_FILE_KEYS = ("file", "walls_file", "walkable_file")


def missing_data(path: str | Path) -> list:
    """The data files a scene file names in its ``[[placement]]`` and ``[[effects]]`` tables (recordings, floor plans:
    :data:`DATA_FILE_KEYS`) that do not exist, as resolved paths. Scenes that replay data kept beside the repository
    (``../shared/data/pedestrian``) are left out of test and benchmark sweeps on a machine without it
    (:func:`shipped_scenes`); an unreadable file names none (loading it says what is wrong)."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return []
    tables = [t for key in ("placement", "effects") for t in (doc.get(key) or []) if isinstance(t, dict)]
    named = [t[k] for t in tables for k in DATA_FILE_KEYS if isinstance(t.get(k), str)]
    return [str((path.parent / f).resolve()) for f in named if not (path.parent / f).exists()]


def shipped_scenes(folder: str | Path) -> list:
    """The scene files of ``folder`` (sorted) whose data files exist (:func:`missing_data`)."""
    return [p for p in sorted(Path(folder).glob("*.toml")) if not missing_data(p)]


def parse_scene(doc: dict, path: str | Path) -> Scene:
    """Validate an already-parsed TOML document ``doc`` read from ``path``."""
    path = Path(path)
    try:
        return _Parser(doc, path).scene()
    except ParamError as e:
        raise SceneError(str(path), e.key, e.message) from None


class _Parser:
    def __init__(self, doc: dict, path: Path):
        self.doc, self.path, self.shown = doc, path, str(path)
        self.base = path.absolute().parent

    def fail(self, key: str, message: str):
        raise SceneError(self.shown, key, message)

    def table(self, key: str) -> dict:
        v = self.doc.get(key, {})
        if not isinstance(v, dict):
            self.fail(key, f"expected a table [{key}], got {v!r}")
        return v

    def scene(self) -> Scene:
        doc = self.doc
        for k in doc:
            if k not in TOP_LEVEL_KEYS:
                self.fail(k, f"unknown key; accepted: {', '.join(TOP_LEVEL_KEYS)}")
        top = {k: (p.check(k, doc[k]) if k in doc else p.default) for k, p in TOP_SCHEMA.items()}
        if not (0.0 < top["dt"] <= 1.0):
            self.fail("dt", f"expected 0 < dt <= 1 (seconds), got {doc.get('dt')!r}")
        name = top["name"] if top["name"] is not None else self.path.stem
        if not name:
            self.fail("name", "expected a non-empty string")

        characters = self.characters(top["seed"])
        placements = self.placements(characters)
        effects = self.effects()
        if any(e.name == "obstacles" and (e.params.get("file") or e.params.get("layer")) for e in effects):
            from crowd.scene_routing import apply_obstacle_file

            apply_obstacle_file(effects, self.fail, self.base)  # the obstacles' floor-plan file
        if any(e.name == "obstacles" and (e.params.get("walls_file") or e.params.get("walls_layer")) for e in effects):
            from crowd.scene_routing import apply_obstacle_walls

            apply_obstacle_walls(effects, self.fail, self.base)  # walls around a floor plan's walkable area
        props = parse_props(self.array_of_tables("props", False), effects, self.base, self.fail)
        if any(e.name == "routing" for e in effects):  # walkable area, walls, waypoints; routing installed first
            from crowd.scene_routing import apply_routing

            apply_routing(effects, characters, self.fail, self.base)
        from crowd.scene_journeys import parse_journeys

        effects = parse_journeys(doc, effects, placements, characters, self.fail)  # [[stages]], [[journeys]], ...
        terrain = self.terrain()
        self.effect_requirements(effects, placements, terrain)
        camera = self.camera()
        render = self.render()
        lod_table = dict(self.table("lod"))
        mode = validate(LOD_SCHEMA, {"mode": lod_table.pop("mode")} if "mode" in lod_table else {}, "lod")["mode"]
        from lod.temporal.selection import LOD_COMMON_PARAMS  # (imports numba: only when a scene is loaded)

        common = {k: lod_table.pop(k) for k in list(lod_table) if k in LOD_COMMON_PARAMS}
        lod_common = validate(LOD_COMMON_PARAMS, common, "lod")  # keys of every mode (keyframed selection)
        lod = {"mode": mode, **validate(_mode_params(mode), lod_table, "lod")}
        out = validate(OUTPUT_SCHEMA, self.table("output"), "output")
        if out["dir"] is not None and not out["dir"].strip():
            self.fail("output.dir", "expected a non-empty directory path")
        out_dir = Path(out["dir"] if out["dir"] is not None else Path("out") / name)
        from crowd.measurement import parse_measurements

        measurements = parse_measurements(doc.get("measurement"), self.fail)
        return Scene(path=self.path.absolute(), name=name, seed=top["seed"], dt=top["dt"],
                     substeps=top["substeps"], frames=top["frames"], characters=tuple(characters),
                     placements=tuple(placements), effects=tuple(effects), camera=camera, render=render,
                     lod_mode=lod["mode"], output_dir=out_dir.absolute(), terrain=terrain,
                     lod_params=tuple((k, v) for k, v in lod.items() if k != "mode"),
                     terrain_lod=tuple(getattr(self, "_terrain_lod", {}).items()) if terrain is not None else (),
                     lod_common=tuple(lod_common.items()), props=tuple(props), trajectories=out["trajectories"],
                     measurements=measurements, video=out["video"])

    # -- [[characters]] ------------------------------------------------------------------------------------------------
    def array_of_tables(self, key: str, required: bool) -> list:
        v = self.doc.get(key)
        if v is None:
            if required:
                self.fail(key, f"required: at least one [[{key}]] table")
            return []
        if not isinstance(v, list) or not all(isinstance(t, dict) for t in v):
            self.fail(key, f"expected an array of tables [[{key}]], got {v!r}")
        if required and not v:
            self.fail(key, f"required: at least one [[{key}]] table")
        return v

    def characters(self, scene_seed: int) -> list:
        out, names = [], {}
        for i, t in enumerate(self.array_of_tables("characters", True)):
            where = f"characters[{i}]"
            c = validate(CHARACTER_SCHEMA, {k: v for k, v in t.items() if k != "variation"}, where)
            if not c["name"]:
                self.fail(f"{where}.name", "expected a non-empty string")
            if c["name"] in names:
                self.fail(f"{where}.name", f"duplicate character name {c['name']!r} (also characters[{names[c['name']]}])")
            names[c["name"]] = i
            if (c["generator"] is None) == (c["file"] is None):
                self.fail(where, "expected exactly one of `generator` (one of "
                          + ", ".join(map(repr, GENERATORS)) + ") or `file` (a glTF file)")
            if c["scale"] <= 0.0:
                self.fail(f"{where}.scale", f"expected > 0, got {t['scale']!r}")
            file = None
            if c["file"] is not None:
                if c["triangles"] is not None:
                    self.fail(f"{where}.triangles", "only accepted with `generator`; a glTF file keeps its own mesh")
                if c["dance"]:
                    self.fail(f"{where}.dance", "only accepted with `generator`; a glTF file keeps its own clips")
                file = (self.base / c["file"]).resolve()
                if file.suffix.lower() not in GLTF_SUFFIXES:
                    self.fail(f"{where}.file", f"expected a glTF file ({', '.join(GLTF_SUFFIXES)}), got {c['file']!r}")
                if not file.is_file():
                    self.fail(f"{where}.file", f"file not found: {file}")
            triangles = c["triangles"]
            if c["generator"] is not None and triangles is None:
                triangles = DEFAULT_TRIANGLES
            out.append(CharacterSpec(name=c["name"], generator=c["generator"], file=file, triangles=triangles,
                                     seed=c["seed"] if c["seed"] is not None else scene_seed,
                                     scale=c["scale"], fps=c["fps"], radius=c["radius"], dance=c["dance"],
                                     variation=parse_variation(t.get("variation"), f"{where}.variation",
                                                             c["generator"], self.fail)))
        return out

    # -- [[placement]] -------------------------------------------------------------------------------------------------
    def placements(self, characters: list) -> list:
        from sim.placement import PLACEMENTS

        names = [c.name for c in characters]
        out = []
        for i, t in enumerate(self.array_of_tables("placement", True)):
            where = f"placement[{i}]"
            kind = t.get("kind")
            if not isinstance(kind, str) or kind not in PLACEMENTS:  # a list/table kind is unhashable
                self.fail(f"{where}.kind", f"expected one of {', '.join(map(repr, PLACEMENTS))}, got {kind!r}"
                          if kind is not None else f"required, one of {', '.join(map(repr, PLACEMENTS))}")
            char = t.get("character")
            choices = None
            if kind == "trajectories" and isinstance(char, dict):  # recorded people drawn as characters by weight
                choices = self.character_choices(char, names, f"{where}.character")
                char = names[choices[0][0]]
            if char is None:
                self.fail(f"{where}.character", f"required, one of {', '.join(map(repr, names))}")
            if not isinstance(char, str) or char not in names:
                self.fail(f"{where}.character", f"unknown character {char!r}; defined: {', '.join(map(repr, names))}")
            clip = t.get("clip")
            if clip is not None and not isinstance(clip, str):
                self.fail(f"{where}.clip", f"expected a clip name (string), got {clip!r}")
            clip = clip or None
            schema = PLACEMENTS[kind][0]
            # the common keys are the loader's; a kind's schema may declare them too (then they pass through)
            rest = {k: v for k, v in t.items() if k not in PLACEMENT_COMMON or k in schema}
            try:
                params = validate(schema, rest, where)
            except ParamError as e:
                if e.message.startswith("unknown key; accepted: "):
                    accepted = sorted(set(schema) | set(PLACEMENT_COMMON))
                    raise SceneError(self.shown, e.key, "unknown key; accepted: " + ", ".join(accepted)) from None
                raise
            if kind == "trajectories":
                params["recording"] = self.recording(params, where)
                params["choices"] = choices or [(names.index(char), 1.0)]
            out.append(PlacementSpec(kind=kind, character=names.index(char), clip=clip, params=params, index=i))
        return out

    def character_choices(self, table: dict, names: list, key: str) -> list:
        """``[(character index, weight), ...]`` of a choice ``{name = weight, ...}`` (weights > 0)."""
        if not table:
            self.fail(key, "expected a character name or a table {name = weight, ...} with at least one entry")
        out = []
        for name, w in table.items():
            if name not in names:
                self.fail(f"{key}.{name}", f"unknown character {name!r}; defined: {', '.join(map(repr, names))}")
            if isinstance(w, bool) or not isinstance(w, (int, float)) or not (w > 0 and w < float("inf")):
                self.fail(f"{key}.{name}", f"expected a weight > 0, got {w!r}")
            out.append((names.index(name), float(w)))
        return out

    def recording(self, params: dict, where: str):
        """The recording of a trajectories placement (``sim.replay.recording.load``), its file relative to the
        scene; bad input as a SceneError naming the key and the file."""
        from sim.replay.recording import load

        try:
            return load(self.base / params["file"], params["format"] or None, params["unit"] or None,
                        params["frame_rate"] or None)
        except ParamError as e:
            self.fail(f"{where}.{e.key}", e.message)

    # -- effects -------------------------------------------------------------------------------------------------------
    def effects(self) -> list:
        from sim.systems import EFFECTS, effect_module

        v = self.doc.get("effects", [])
        if not isinstance(v, list):
            self.fail("effects", f"expected an array of effect names or tables with a `name`, got {v!r}")
        accepted = ", ".join(map(repr, EFFECTS))
        out, seen = [], {}
        for i, e in enumerate(v):
            where = f"effects[{i}]"
            if isinstance(e, str):
                name, table = e, {}
            elif isinstance(e, dict):
                name = e.get("name")
                if not isinstance(name, str):
                    self.fail(f"{where}.name", f"required, one of {accepted}")
                table = {k: x for k, x in e.items() if k != "name"}
            else:
                self.fail(where, f"expected an effect name or a table with a `name`, got {e!r}")
            if name not in EFFECTS:
                self.fail(where, f"unknown effect {name!r}; accepted: {accepted}")
            if name in seen:
                self.fail(where, f"effect {name!r} is listed twice (also effects[{seen[name]}])")
            seen[name] = i
            params = validate(effect_module(name).PARAMS, table, where)
            out.append(EffectSpec(name=name, params=params, index=i))
        return out

    def effect_requirements(self, effects: list, placements: list, terrain) -> None:
        """Effects that need another part of the scene (checked here, before anything is built)."""
        for e in effects:
            if e.name == "terrain_follow" and terrain is None:
                self.fail(f"effects[{e.index}]", "effect 'terrain_follow' needs a [terrain] table")
            if e.name == "instancing" and not any(p.kind == "hierarchy" for p in placements):
                self.fail(f"effects[{e.index}]", "effect 'instancing' needs a [[placement]] of kind 'hierarchy'")

    # -- [terrain] -----------------------------------------------------------------------------------------------------
    def terrain(self) -> dict | None:
        if "terrain" not in self.doc:
            return None
        t = dict(self.table("terrain"))
        import sim.terrain
        from lod.temporal.terrain_keyframes import TERRAIN_LOD_PARAMS

        # the view-dependent terrain's keys (lod, lod_tau, ...) belong to the LOD layer; the rest to sim.terrain
        lod_keys = {k: t.pop(k) for k in list(t) if k in TERRAIN_LOD_PARAMS}
        self._terrain_lod = validate(TERRAIN_LOD_PARAMS, lod_keys, "terrain")
        try:
            cfg = validate(sim.terrain.PARAMS, t, "terrain")
        except ParamError as e:
            if "unknown key" in e.message:  # name the LOD keys among the accepted ones
                accepted = ", ".join(sorted([*sim.terrain.PARAMS, *TERRAIN_LOD_PARAMS]))
                raise ParamError(e.key, f"unknown key; accepted: {accepted}") from None
            raise
        size = cfg.get("size")
        if size is not None and not (size[0] > 0 and size[1] > 0):
            self.fail("terrain.size", f"expected two numbers > 0, got {t['size']!r}")
        if cfg.get("file"):
            f = (self.base / cfg["file"]).resolve()
            if not f.is_file():
                self.fail("terrain.file", f"file not found: {f}")
            cfg["file"] = str(f)
        return cfg

    # -- [camera] ------------------------------------------------------------------------------------------------------
    def camera(self) -> CameraSpec:
        raw = self.table("camera")
        c = validate(CAMERA_SCHEMA, raw, "camera")
        if c["near"] <= 0.0:
            self.fail("camera.near", f"expected > 0, got {raw['near']!r}")
        if c["far"] <= c["near"]:
            self.fail("camera.far", f"expected > camera.near ({c['near']}), got {raw.get('far', c['far'])!r}")
        modes = [k for k in ("keys", "path_file") if c[k] is not None]
        if len(modes) == 2:
            self.fail("camera", "expected at most one of `keys` or `path_file`")
        if modes and (c["position"] is not None or c["target"] is not None):
            self.fail(f"camera.{modes[0]}", "replaces `position`/`target`; give either a fixed pose or a path")
        keys, path_file = (), None
        if c["keys"] is not None:
            keys = self.camera_keys(c["keys"], "camera.keys")
        elif c["path_file"] is not None:
            from lod.camera_path import CameraPathError, load_path

            path_file = (self.base / c["path_file"]).resolve()
            if not path_file.is_file():
                self.fail("camera.path_file", f"file not found: {path_file}")
            try:
                path = load_path(path_file)
            except CameraPathError as e:
                self.fail("camera.path_file", str(e))
            keys = tuple(CameraKey(float(t), tuple(map(float, p)), tuple(map(float, g)))
                         for t, p, g in zip(path.times, path.positions, path.targets))
        pos = tuple(c["position"] or DEFAULT_CAMERA_POSITION)
        tgt = tuple(c["target"] or DEFAULT_CAMERA_TARGET)
        if not keys and math.dist(pos, tgt) == 0.0:
            self.fail("camera.target", "must differ from camera.position")
        return CameraSpec(fov=c["fov"], near=c["near"], far=c["far"], position=pos, target=tgt, keys=keys,
                          path_file=path_file)

    def camera_keys(self, raw: list, where: str) -> tuple:
        if not raw:
            self.fail(where, "expected at least one key {time, position, target}")
        keys = []
        for i, k in enumerate(raw):
            w = f"{where}[{i}]"
            if not isinstance(k, dict):
                self.fail(w, f"expected a table {{time, position, target}}, got {k!r}")
            v = validate(CAMERA_KEY_SCHEMA, k, w)
            if keys and v["time"] <= keys[-1].time:
                self.fail(f"{w}.time", f"expected times strictly increasing, got {k['time']!r} after {keys[-1].time}")
            if math.dist(v["position"], v["target"]) == 0.0:
                self.fail(f"{w}.target", "must differ from position")
            keys.append(CameraKey(v["time"], tuple(v["position"]), tuple(v["target"])))
        return tuple(keys)

    # -- [render] ------------------------------------------------------------------------------------------------------
    def render(self) -> RenderSpec:
        raw = self.table("render")
        r = validate(RENDER_SCHEMA, raw, "render")
        size = parse_size(r["size"])
        if size is None:
            self.fail("render.size", f"expected [width, height], two integers in {SIZE_RANGE[0]} ..= {SIZE_RANGE[1]}, "
                      f"got {raw['size']!r}")
        bg = r["background"]
        if not all(0.0 <= x <= 1.0 for x in bg):
            self.fail("render.background", f"expected three numbers in [0, 1], got {raw['background']!r}")
        try:
            light = _light.make_light(r["light_dir"], r["light_color"], r["ambient"])
        except _light.LightError as e:
            self.fail(f"render.{e.key}", e.message)
        return RenderSpec(size=size, background=tuple(bg), png_every=r["png_every"], ground=r["ground"], light=light,
                          shadows=r["shadows"], shadow_distance=r["shadow_distance"],
                          shadow_map_size=r["shadow_map_size"], raster_threshold=r["raster_threshold"])


def parse_size(value: Any) -> tuple | None:
    """``[w, h]`` (list of two ints) or ``"WxH"`` -> (w, h) within SIZE_RANGE, else None."""
    if isinstance(value, str):
        m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", value)
        if not m:
            return None
        value = [int(m[1]), int(m[2])]
    if (not isinstance(value, (list, tuple)) or len(value) != 2
            or not all(isinstance(x, int) and not isinstance(x, bool) for x in value)):
        return None
    lo, hi = SIZE_RANGE
    if not all(lo <= x <= hi for x in value):
        return None
    return int(value[0]), int(value[1])
