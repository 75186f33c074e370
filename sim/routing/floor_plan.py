"""Floor plans from files: the walkable area of the ``routing`` effect read from the drawings the field keeps.

Pedestrian experiments and simulators keep their geometry as files (PedPy's walkable areas as WKT, GIS exports as
GeoJSON); a scene names one with ``walkable_file`` in place of typing the polygons (``walkable``). The file's plane
coordinates (x, y), metres, are the scene's floor (x, z), as PedPy's trajectories are (``crowd.trajectories``).

Formats, by the file's suffix:

- ``.wkt``: one WKT geometry (shapely): a POLYGON, a MULTIPOLYGON or a GEOMETRYCOLLECTION of them;
- ``.geojson`` / ``.json``: a GeoJSON geometry, Feature or FeatureCollection (shapely.geometry.shape of each
  geometry), its Polygon / MultiPolygon parts;
- ``.dxf``: a drawing (ezdxf): the closed LWPOLYLINE / POLYLINE / CIRCLE / ELLIPSE / SPLINE entities and the
  boundary paths of HATCH entities of its model space, on every layer or on the ``layer`` asked for, curves
  flattened to :data:`DXF_FLATTENING` metres; rings nested in rings are holes (even-odd: the area is the symmetric
  difference of every ring's polygon, as a hatch's boundaries are read). An open polyline or a self-intersecting
  ring is named by layer, entity type and handle. LINE, ARC and text entities are not areas and are left out;
- the geometry a recording stores with it, read by PedPy's loaders: ``.sqlite`` a JuPedSim trajectory file,
  ``.scenario`` a Vadere scenario (obstacles touching its bounding box: the box grown by 1 micrometre, as PedPy
  asks).

The polygons are united (touching pieces become one area) and returned as the ``walkable`` list the routing effect
takes: ``[{"points": [[x, z], ...], "holes": [[[x, z], ...], ...]}, ...]``, outer rings counter-clockwise. A file that
is missing, empty, unreadable, of another format, not a closed area (lines, points) or not a simple area
(self-intersecting rings) raises :class:`FloorPlanError`, one sentence naming the file and what is wrong.
"""
from __future__ import annotations

import json
from pathlib import Path

#: suffixes read as WKT, as GeoJSON and as DXF
WKT_SUFFIXES = (".wkt",)
GEOJSON_SUFFIXES = (".geojson", ".json")
DXF_SUFFIXES = (".dxf",)
#: suffixes of recordings whose geometry PedPy reads: JuPedSim SQLite, Vadere scenario
RECORDING_SUFFIXES = (".sqlite", ".scenario")
#: largest distance (metres) between a DXF curve (arc, circle, spline) and the polygon that stands for it
DXF_FLATTENING = 0.01
#: DXF entities whose closed outlines are rings of the area
DXF_AREAS = ("LWPOLYLINE", "POLYLINE", "CIRCLE", "ELLIPSE", "SPLINE", "HATCH")


class FloorPlanError(ValueError):
    """A floor-plan file the code cannot take; the message names the file and what is wrong."""


def _fail(path: Path, what: str):
    raise FloorPlanError(f"{path}: {what}")


def _geometries_of_geojson(path: Path, doc) -> list:
    from shapely.geometry import shape

    if not isinstance(doc, dict) or "type" not in doc:
        _fail(path, "expected a GeoJSON object (a geometry, Feature or FeatureCollection)")
    kind = doc["type"]
    if kind == "FeatureCollection":
        feats = doc.get("features")
        if not isinstance(feats, list):
            _fail(path, "FeatureCollection without a `features` list")
        out = []
        for i, f in enumerate(feats):
            if not isinstance(f, dict) or f.get("geometry") is None:
                _fail(path, f"feature {i} has no geometry")
            out.append((f"feature {i}", f["geometry"]))
    elif kind == "Feature":
        if doc.get("geometry") is None:
            _fail(path, "Feature without a geometry")
        out = [("the feature", doc["geometry"])]
    else:
        out = [("the geometry", doc)]
    geoms = []
    for what, g in out:
        try:
            geoms.append((what, shape(g)))
        except Exception as e:  # shapely raises several kinds for malformed input
            _fail(path, f"{what} is not a valid GeoJSON geometry ({type(e).__name__}: {str(e)[:80]})")
    return geoms


def _dxf_geometries(path: Path, layer: str | None) -> list:
    """[(what, polygon)]: the DXF's area as the symmetric difference of its closed rings (module docstring)."""
    import ezdxf
    import shapely
    from ezdxf import path as ezpath
    from shapely.geometry import Polygon

    try:
        doc = ezdxf.readfile(str(path))
    except (OSError, ezdxf.DXFError) as e:
        _fail(path, f"not a readable DXF drawing ({type(e).__name__}: {str(e).splitlines()[0][:100] if str(e) else ''})")
    rings, layers = [], set()
    for e in doc.modelspace():
        kind = e.dxftype()
        lay = str(e.dxf.get("layer", "0"))
        layers.add(lay)
        if kind not in DXF_AREAS or (layer is not None and lay != layer):
            continue
        name = f"layer {lay!r}, {kind} (handle {e.dxf.handle})"
        try:
            paths = list(ezpath.from_hatch(e)) if kind == "HATCH" else [ezpath.make_path(e)]
        except Exception as err:  # ezdxf's own errors for entities it cannot make a path of
            _fail(path, f"{name}: cannot read its outline ({type(err).__name__})")
        for k, p in enumerate(paths):
            what = name if len(paths) == 1 else f"{name}, boundary {k}"
            pts = [(float(v.x), float(v.y)) for v in p.flattening(DXF_FLATTENING)]
            closed = p.is_closed or (kind == "LWPOLYLINE" and bool(e.closed)) or \
                (kind == "POLYLINE" and bool(e.is_closed))
            if not closed:
                _fail(path, f"{what} is an open polyline, not an area (close it)")
            ring = Polygon(pts)
            if not ring.is_valid:
                _fail(path, f"{what} is not a simple area: {shapely.is_valid_reason(ring)}")
            if ring.area > 0.0:
                rings.append(ring)
    if not rings:
        where = f" on layer {layer!r}" if layer is not None else ""
        _fail(path, f"no closed polyline or hatch{where} (layers: {', '.join(sorted(layers)) or 'none'})")
    area = rings[0]
    for r in rings[1:]:  # even-odd: a ring inside another is a hole of it
        area = area.symmetric_difference(r)
    return [(f"the drawing{' on layer ' + repr(layer) if layer else ''}", area)]


def _recording_geometry(path: Path, suffix: str) -> list:
    """[(what, polygon)]: the walkable area a JuPedSim or Vadere file stores (PedPy's loaders)."""
    try:
        import pedpy
    except ImportError:
        _fail(path, "reading a recording's geometry needs PedPy (the report extra: pip install -e '.[report]')")
    try:
        if suffix == ".sqlite":
            area = pedpy.load_walkable_area_from_jupedsim_sqlite(trajectory_file=path)
        else:
            try:
                area = pedpy.load_walkable_area_from_vadere_scenario(vadere_scenario_file=path)
            except pedpy.errors.LoadTrajectoryError as e:
                if "touch the bound" not in str(e):
                    raise
                area = pedpy.load_walkable_area_from_vadere_scenario(vadere_scenario_file=path, margin=1e-6)
    except Exception as e:  # PedPy's loader errors, sqlite3 and JSON errors of a broken file
        _fail(path, f"no walkable area in it ({type(e).__name__}: {str(e).splitlines()[0][:120] if str(e) else ''})")
    return [("the recording's walkable area", area.polygon)]


def read_geometries(path, layer: str | None = None) -> list:
    """[(what, shapely geometry)] of a floor-plan file (module docstring: formats); ``layer``: a DXF layer."""
    import shapely

    path = Path(path)
    suffix = path.suffix.lower()
    known = WKT_SUFFIXES + GEOJSON_SUFFIXES + DXF_SUFFIXES + RECORDING_SUFFIXES
    if suffix not in known:
        _fail(path, f"unknown floor-plan format {suffix or '(no suffix)'!r}; expected one of {', '.join(known)}")
    if layer is not None and suffix not in DXF_SUFFIXES:
        _fail(path, f"a layer ({layer!r}) is asked for, but only a DXF drawing has layers")
    if suffix in DXF_SUFFIXES + RECORDING_SUFFIXES:
        if not path.is_file():
            _fail(path, "file not found")
        if path.stat().st_size == 0:
            _fail(path, "the file is empty")
        return _dxf_geometries(path, layer) if suffix in DXF_SUFFIXES else _recording_geometry(path, suffix)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        _fail(path, "file not found")
    except (OSError, UnicodeDecodeError) as e:
        _fail(path, f"cannot read it ({type(e).__name__})")
    if not text.strip():
        _fail(path, "the file is empty")
    if suffix in WKT_SUFFIXES:
        try:
            return [("the geometry", shapely.from_wkt(text.strip()))]
        except Exception as e:  # shapely.errors.GEOSException and kin
            _fail(path, f"not valid WKT ({str(e).splitlines()[0][:100]})")
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        _fail(path, f"not valid JSON (line {e.lineno}, column {e.colno}: {e.msg})")
    return _geometries_of_geojson(path, doc)


def _ring(coords) -> list:
    """[[x, z], ...] of a closed shapely ring, its closing point left out."""
    pts = [[float(x), float(y)] for x, y, *_ in coords]
    return pts[:-1] if len(pts) > 1 and pts[0] == pts[-1] else pts


def load_walkable(path, layer: str | None = None) -> list:
    """The ``walkable`` list of the routing effect (module docstring) from the floor-plan file ``path`` (a DXF:
    the entities on ``layer`` only, when given).

    Raises
    ------
    FloorPlanError
        One sentence naming the file and what is wrong (format, emptiness, not a closed or not a simple area).
    """
    import shapely
    from shapely.geometry import Polygon
    from shapely.geometry.polygon import orient

    path = Path(path)
    polys = []
    for what, g in read_geometries(path, layer):
        if g.is_empty:
            _fail(path, f"{what} is empty")
        parts, todo = [], [g]
        while todo:  # collections and multi-polygons flattened to their pieces
            q = todo.pop(0)
            if hasattr(q, "geoms") and not isinstance(q, Polygon):
                todo[:0] = list(q.geoms)
            else:
                parts.append(q)
        for k, p in enumerate(parts):
            name = what if len(parts) == 1 else f"{what}, part {k}"
            if not isinstance(p, Polygon):
                closed = getattr(p, "is_closed", False)
                _fail(path, f"{name} is a {p.geom_type}, not an area" + (
                    " (a closed line: write it as a POLYGON)" if closed else " (not closed)"))
            if not p.is_valid:
                why = shapely.is_valid_reason(p)
                _fail(path, f"{name} is not a simple area: {why}")
            if p.area <= 0.0:
                _fail(path, f"{name} has no area")
            polys.append(p)
    if not polys:
        _fail(path, "no polygon in the file")
    union = shapely.union_all(polys)
    out = []
    for p in getattr(union, "geoms", [union]):
        p = orient(p, 1.0)
        out.append({"points": _ring(p.exterior.coords), "holes": [_ring(h.coords) for h in p.interiors]})
    return out
