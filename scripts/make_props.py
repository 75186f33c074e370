"""Write the small prop meshes the shipped scenes use into ``scenes/props/`` (reproducible).

    python scripts/make_props.py [--out scenes/props]

- ``stand.glb``: an exhibition stand (octagonal platform of radius 2.5 m, a kiosk and a
  sign), glTF binary with vertex colours (scenes/exhibition.toml).
- ``desk.obj``: an office desk, 1.6 x 0.8 m, 0.77 m high, with a monitor (scenes/office.toml).
- ``planter.ply``: a planter box with a round bush (an icosphere: the prop whose LOD chain
  shows), and ``lamp.stl``: a lamp post, Z up as STL files often are (scenes/quickstart.toml).

Every file is built from trimesh primitives with fixed parameters, so a rerun writes the
same geometry; each stays well under 100 kB. Files are written atomically.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from sim.atomic_io import write_atomic  # noqa: E402


def _part(mesh: trimesh.Trimesh, rgb, at=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    mesh = mesh.copy()
    mesh.apply_translation(at)
    mesh.visual.vertex_colors = np.tile(np.r_[np.round(np.asarray(rgb) * 255), 255].astype(np.uint8),
                                        (len(mesh.vertices), 1))
    return mesh


def _box(size, rgb, at):
    return _part(trimesh.creation.box(extents=size), rgb, at)


def stand() -> trimesh.Trimesh:
    plat = trimesh.creation.cylinder(radius=2.5, height=0.3, sections=8)
    plat.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))  # axis Z -> Y
    return trimesh.util.concatenate([
        _part(plat, (0.75, 0.72, 0.66), (0, 0.15, 0)),
        _box((1.2, 2.2, 1.2), (0.85, 0.85, 0.82), (0, 1.4, 0)),
        _box((2.6, 0.8, 0.1), (0.15, 0.35, 0.65), (0, 2.9, 0)),
        _box((0.1, 0.4, 0.1), (0.3, 0.3, 0.3), (0, 2.45, 0)),
    ])


def desk() -> trimesh.Trimesh:
    parts = [_box((1.6, 0.04, 0.8), (0.72, 0.58, 0.42), (0, 0.75, 0))]
    for x in (-0.75, 0.75):
        for z in (-0.35, 0.35):
            parts.append(_box((0.05, 0.73, 0.05), (0.25, 0.25, 0.27), (x, 0.365, z)))
    parts.append(_box((0.55, 0.35, 0.03), (0.08, 0.08, 0.09), (0, 1.0, -0.25)))
    parts.append(_box((0.06, 0.1, 0.06), (0.2, 0.2, 0.2), (0, 0.82, -0.25)))
    return trimesh.util.concatenate(parts)


def planter() -> trimesh.Trimesh:
    bush = trimesh.creation.icosphere(subdivisions=3, radius=0.55)
    return trimesh.util.concatenate([_box((1.0, 0.5, 1.0), (0.45, 0.38, 0.32), (0, 0.25, 0)),
                                     _part(bush, (0.22, 0.42, 0.2), (0, 0.85, 0))])


def lamp() -> trimesh.Trimesh:
    pole = trimesh.creation.cylinder(radius=0.06, height=3.0, sections=12)
    pole.apply_translation((0, 0, 1.5))
    head = trimesh.creation.cylinder(radius=0.25, height=0.15, sections=12)
    head.apply_translation((0, 0, 3.05))
    return trimesh.util.concatenate([pole, head])  # Z up (the scene says up = "z")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent.parent / "scenes" / "props"))
    args = ap.parse_args(argv)
    out = Path(args.out)
    for name, mesh in (("stand.glb", stand()), ("desk.obj", desk()), ("planter.ply", planter()),
                       ("lamp.stl", lamp())):
        data = mesh.export(file_type=name.rsplit(".", 1)[1])
        path = write_atomic(out / name, data if isinstance(data, (bytes, str)) else bytes(data))
        print(f"{path}: {len(mesh.faces)} triangles, {path.stat().st_size / 1000:.1f} kB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
