"""Props: static meshes placed in the world (the scene's ``[[props]]`` tables).

A prop is a static mesh file (OBJ, PLY, STL, static glTF/GLB) read with trimesh,
placed by list or grid (position, yaw, scale, like ``sim.placement``), and
optionally an obstacle: ``obstacle = true`` derives the obstacle from the
mesh's floor projection (``footprint = "hull"``: the convex hull of the
vertices projected on XZ; ``"circle"``: the circle about the projection's
bounding-box centre through its farthest vertex; ``"box"``: the projection's
bounding box, turned with the prop's yaw) and hands it to the ``obstacles``
effect (:mod:`sim.obstacles`), so what stops agents is what one sees.

This module only reads meshes and computes placements and footprints (sim may
use trimesh to read a mesh); the representations (LOD chains) are built in
``lod.props`` and drawn by ``render.world.draw``.

Conventions: a prop's model is Y up (as glTF; ``up = "z"`` turns a Z-up file,
e.g. most STL, upright) and in metres. Yaw about +Y maps local +Z to
``(sin yaw, cos yaw)`` on XZ, as the characters' heading and the obstacles'
box yaw.
"""
from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from sim.errors import AssetError
from sim.params import Param, ParamError, validate

#: mesh file suffixes accepted by ``[[props]] file``
PROP_SUFFIXES = (".obj", ".ply", ".stl", ".glb", ".gltf")
#: footprints accepted by ``[[props]] footprint``
FOOTPRINTS = ("hull", "circle", "box")
#: colour of a prop whose file has none and which sets no ``color``
DEFAULT_PROP_COLOR = (0.62, 0.6, 0.56)
#: most triangles a prop file may hold (a prop is scenery, not a character)
MAX_PROP_TRIANGLES = 2_000_000


class _Vec3List(Param):
    def check(self, key, value):
        if not isinstance(value, list) or not value:
            raise ParamError(key, f"expected a non-empty list of [x, y, z], got {value!r}")
        return [Param("vec3").check(f"{key}[{i}]", v) for i, v in enumerate(value)]


class _FloatList(Param):
    def check(self, key, value):
        if not isinstance(value, list):
            raise ParamError(key, f"expected a list of numbers, got {value!r}")
        return [Param("float").check(f"{key}[{i}]", v) for i, v in enumerate(value)]


#: keys of a ``[[props]]`` table (validated with :func:`sim.params.validate`)
PROP_PARAMS: dict[str, Param] = {
    "name": Param("str", "", doc="label in messages and representation keys; default props[i]"),
    "file": Param("str", doc="mesh file (.obj, .ply, .stl, .glb, .gltf), relative to the scene file"),
    "kind": Param("str", "list", choices=("list", "grid"), doc="placement: explicit positions or a grid"),
    "positions": _Vec3List("list", None, doc="kind list: [[x, y, z], ...] metres"),
    "yaws": _FloatList("list", [], doc="kind list: per-prop yaw, degrees (same length as positions)"),
    "rows": Param("int", 1, min=1, max=100_000, doc="kind grid: props along z"),
    "cols": Param("int", 1, min=1, max=100_000, doc="kind grid: props along x"),
    "spacing": Param("vec2", [2.0, 2.0], doc="kind grid: metres between props along x, z"),
    "origin": Param("vec3", [0.0, 0.0, 0.0], doc="kind grid: position of the first prop"),
    "yaw": Param("float", 0.0, doc="yaw of every prop about +Y, degrees (added to yaws)"),
    "scale": Param("float", 1.0, min=1e-4, max=1e4, doc="uniform scale"),
    "up": Param("str", "y", choices=("y", "z"), doc="the file's up axis"),
    "color": Param("vec3", None, doc="linear RGB in [0, 1]; default: the file's colours (grey without)"),
    "obstacle": Param("bool", False, doc="derive an obstacle from the footprint (obstacles effect)"),
    "footprint": Param("str", "hull", choices=FOOTPRINTS, doc="obstacle shape from the floor projection"),
}


@dataclass(frozen=True)
class PropMesh:
    """A prop's mesh in model space (Y up, metres).

    positions : (V, 3) float64; faces : (F, 3) int64 (F >= 1); colors : (V, 4) float32 in [0, 1]
    """

    positions: np.ndarray
    faces: np.ndarray
    colors: np.ndarray

    @property
    def n_triangles(self) -> int:
        return int(self.faces.shape[0])


# ---------------------------------------------------------------------------------------------------------------------
# reading
# ---------------------------------------------------------------------------------------------------------------------
def _gltf_json(path: Path) -> dict | None:
    """The JSON document of a .gltf/.glb file (None when it cannot be read: trimesh reports it)."""
    try:
        data = path.read_bytes()
        if path.suffix.lower() == ".gltf":
            return json.loads(data.decode("utf-8"))
        if len(data) < 20 or data[:4] != b"glTF":
            return None
        n, kind = struct.unpack_from("<II", data, 12)
        if kind != 0x4E4F534A:  # "JSON"
            return None
        return json.loads(data[20:20 + n].decode("utf-8"))
    except (OSError, ValueError, struct.error):
        return None


def _colors_of(geom, n: int) -> np.ndarray | None:
    """(n, 4) float32 vertex colours of a trimesh geometry, or None when it has none."""
    try:
        kind = geom.visual.kind
        if kind in ("vertex", "face"):
            c = np.asarray(geom.visual.vertex_colors, np.float64)[:, :4] / 255.0
            return c.astype(np.float32) if c.shape == (n, 4) else None
        if kind == "texture":
            mat = geom.visual.material
            main = np.asarray(getattr(mat, "main_color", None), np.float64)
            if main.size >= 3:
                c = np.ones((n, 4), np.float32)
                c[:, :3] = main.reshape(-1)[:3] / 255.0
                return c
    except Exception:  # a visual trimesh cannot convert: use the default colour
        return None
    return None


@lru_cache(maxsize=64)
def _load(path: str, mtime_ns: int, up: str) -> PropMesh:
    p = Path(path)
    name = p.name
    if p.suffix.lower() not in PROP_SUFFIXES:
        raise AssetError(f"{name}: unsupported mesh format {p.suffix!r}; accepted: {', '.join(PROP_SUFFIXES)}")
    if p.suffix.lower() in (".glb", ".gltf"):
        doc = _gltf_json(p)
        if doc is not None and (doc.get("skins") or doc.get("animations")):
            what = "skinned" if doc.get("skins") else "animated"
            raise AssetError(f"{name}: a {what} glTF is not a static prop; accepted: a glTF without skins and "
                             "animations (load animated models as [[characters]])")
    import trimesh

    try:
        scene = trimesh.load_scene(str(p))
        geoms = [g for g in scene.dump(concatenate=False) if hasattr(g, "faces")]
    except Exception as e:  # trimesh raises many types for unreadable files
        msg = " ".join(str(e).split())[:160] or type(e).__name__
        raise AssetError(f"{name}: cannot read the mesh ({msg}); accepted: a valid OBJ, PLY, STL or glTF file") \
            from None
    pos, faces, cols, base = [], [], [], 0
    for g in geoms:
        v = np.asarray(g.vertices, np.float64).reshape(-1, 3)
        f = np.asarray(g.faces, np.int64).reshape(-1, 3)
        if not len(f):
            continue
        c = _colors_of(g, len(v))
        if c is None:
            c = np.ones((len(v), 4), np.float32)
            c[:, :3] = DEFAULT_PROP_COLOR
        pos.append(v)
        faces.append(f + base)
        cols.append(c)
        base += len(v)
    if not faces:
        raise AssetError(f"{name}: the file holds no triangles; accepted: a mesh with at least one triangle")
    v, f, c = np.concatenate(pos), np.concatenate(faces), np.concatenate(cols)
    if len(f) > MAX_PROP_TRIANGLES:
        raise AssetError(f"{name}: {len(f):,} triangles; accepted: at most {MAX_PROP_TRIANGLES:,} per prop file")
    if not np.isfinite(v).all() or (v.size and float(np.abs(v).max()) > 1e7):
        raise AssetError(f"{name}: vertex positions are NaN, infinite or beyond 1e7 m; accepted: finite metres")
    if f.min() < 0 or f.max() >= len(v):
        raise AssetError(f"{name}: face indices outside the {len(v)} vertices")
    if up == "z":
        v = np.stack([v[:, 0], v[:, 2], -v[:, 1]], axis=1)
    v.setflags(write=False)
    f.setflags(write=False)
    c.setflags(write=False)
    return PropMesh(v, f, np.clip(c, 0.0, 1.0))


def load_prop_mesh(path, up: str = "y") -> PropMesh:
    """Read a prop mesh file (cached by path and modification time).

    Raises
    ------
    sim.errors.AssetError
        One sentence naming the file: missing, unreadable, no triangles, a
        skinned or animated glTF (refused: props are static), non-finite vertices.
    """
    p = Path(path)
    try:
        mtime = p.stat().st_mtime_ns
    except OSError:
        raise AssetError(f"{p}: file not found; accepted: an existing OBJ, PLY, STL or glTF file") from None
    if not p.is_file():
        raise AssetError(f"{p}: not a file; accepted: an OBJ, PLY, STL or glTF file")
    return _load(str(p.resolve()), mtime, up)


# ---------------------------------------------------------------------------------------------------------------------
# placement and footprints
# ---------------------------------------------------------------------------------------------------------------------
def check_params(cfg: dict, where: str) -> None:
    """Cross-key checks of a validated ``[[props]]`` table (ParamError)."""
    if cfg["kind"] == "list":
        if cfg["positions"] is None:
            raise ParamError(f"{where}.positions", "required for kind 'list': [[x, y, z], ...]")
        if cfg["yaws"] and len(cfg["yaws"]) != len(cfg["positions"]):
            raise ParamError(f"{where}.yaws", f"expected {len(cfg['positions'])} entries (one per position), "
                             f"got {len(cfg['yaws'])}")
    elif cfg["positions"] is not None:
        raise ParamError(f"{where}.positions", "only accepted with kind 'list'; kind 'grid' uses rows, cols, "
                         "spacing and origin")
    if cfg["color"] is not None and not all(0.0 <= x <= 1.0 for x in cfg["color"]):
        raise ParamError(f"{where}.color", f"expected three numbers in [0, 1], got {cfg['color']!r}")


def validate_prop(table: dict, where: str) -> dict:
    """A ``[[props]]`` table validated against :data:`PROP_PARAMS` and :func:`check_params`."""
    cfg = validate(PROP_PARAMS, table, where)
    check_params(cfg, where)
    return cfg


def prop_instances(cfg: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Placements of a validated ``[[props]]`` table.

    Returns
    -------
    positions : (n, 3) float64 metres; yaw : (n,) float64 radians; scale : (n,) float64
    """
    if cfg["kind"] == "grid":
        rows, cols = int(cfg["rows"]), int(cfg["cols"])
        r, c = np.divmod(np.arange(rows * cols, dtype=np.int64), cols)
        o = np.asarray(cfg["origin"], np.float64)
        dx, dz = (float(x) for x in cfg["spacing"])
        pos = np.stack([o[0] + c * dx, np.full(r.shape, o[1]), o[2] + r * dz], axis=1)
        yaw = np.zeros(len(pos))
    else:
        pos = np.asarray(cfg["positions"], np.float64).reshape(-1, 3)
        yaw = np.radians(np.asarray(cfg["yaws"], np.float64)) if cfg["yaws"] else np.zeros(len(pos))
    yaw = yaw + math.radians(float(cfg["yaw"]))
    return pos, yaw, np.full(len(pos), float(cfg["scale"]))


def model_rows(positions: np.ndarray, yaw: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(n, 3, 4) float64 model matrices (rows 0..2) of placements: ``p + R_y(yaw) (s x)``."""
    c, s = np.cos(yaw) * scale, np.sin(yaw) * scale
    m = np.zeros((len(positions), 3, 4))
    m[:, 0, 0], m[:, 0, 2], m[:, 0, 3] = c, s, positions[:, 0]
    m[:, 1, 1], m[:, 1, 3] = scale, positions[:, 1]
    m[:, 2, 0], m[:, 2, 2], m[:, 2, 3] = -s, c, positions[:, 2]
    return m


def footprint(mesh: PropMesh, kind: str, label: str = "prop") -> dict:
    """The model-space footprint of a mesh's floor (XZ) projection.

    Returns ``{"polygon": (k, 2) ccw}`` (hull), ``{"circle": (cx, cz, r)}`` or
    ``{"box": (cx, cz, sx, sz)}``; a projection without area is an AssetError.
    """
    xz = np.asarray(mesh.positions[:, [0, 2]], np.float64)
    lo, hi = xz.min(0), xz.max(0)
    ctr = 0.5 * (lo + hi)
    if kind == "circle":
        r = float(np.sqrt(((xz - ctr) ** 2).sum(1)).max())
        if not r > 0:
            raise AssetError(f"{label}: the mesh's floor projection is a point; a circle footprint needs extent")
        return {"circle": (float(ctr[0]), float(ctr[1]), r)}
    if kind == "box":
        size = hi - lo
        if not (size > 0).all():
            raise AssetError(f"{label}: the mesh's floor projection has no area (size {size.tolist()}); "
                             "accepted for footprint 'box': a mesh with extent along x and z")
        return {"box": (float(ctr[0]), float(ctr[1]), float(size[0]), float(size[1]))}
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(np.unique(xz, axis=0))
    except (QhullError, ValueError):
        raise AssetError(f"{label}: the mesh's floor projection has no area; accepted for footprint 'hull': a "
                         "mesh with extent along x and z (or footprint = 'circle')") from None
    return {"polygon": hull.points[hull.vertices]}  # scipy gives 2-D hull vertices counter-clockwise


def placed_obstacles(fp: dict, positions: np.ndarray, yaw: np.ndarray, scale: np.ndarray) -> dict:
    """Obstacle tables (``sim.obstacles`` PARAMS layout) of a footprint at each placement;
    every one has ``visible = false`` (the prop itself is what is drawn)."""
    out = {"circles": [], "boxes": [], "polygons": []}
    for p, a, s in zip(positions, yaw, scale):
        c, si = math.cos(a), math.sin(a)

        def place(x, z):
            return [float(p[0] + s * (c * x + si * z)), float(p[2] + s * (-si * x + c * z))]

        if "circle" in fp:
            cx, cz, r = fp["circle"]
            out["circles"].append({"center": place(cx, cz), "radius": float(s * r), "height": 0.0,
                                   "visible": False})
        elif "box" in fp:
            cx, cz, sx, sz = fp["box"]
            out["boxes"].append({"center": place(cx, cz), "size": [float(s * sx), float(s * sz)],
                                 "yaw": math.degrees(a), "height": 0.0, "visible": False})
        else:
            out["polygons"].append({"points": [place(x, z) for x, z in fp["polygon"]], "height": 0.0,
                                    "visible": False})
    return out
