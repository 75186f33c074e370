"""Benchmark: bisection terrain LOD vs the full-resolution terrain along a camera path.

Builds the terrain of a scene's ``[terrain]`` table (default ``scenes/horses.toml``)
as a :class:`lod.temporal.terrain.TerrainHierarchy`, flies a scripted camera over it
and prints, per method, the triangles drawn and the CPU time per frame spent on
LOD work (selection or interpolation + building the mesh arrays), the number of
view-dependent selections, the screen-space error against the full-resolution
surface (mean / max pixels) and the flicker (mean / max pixel change of the
drawn surface between consecutive frames). Methods: the full-resolution mesh,
per-frame selection, keyframed selection every n-th frame (§3). A second table
gives the three camera-extrapolation modes' error terms (§4.1) on the same path.

Usage: python scripts/bench_terrain_lod.py [--scene scenes/horses.toml] [--frames 120]
       [--n 8] [--tau 1.0] [--size 1280 720]
"""
from __future__ import annotations

import argparse
import math
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from lod.temporal.terrain_keyframes import TEMPORAL_MODES, TemporalTerrainLOD, pixel_deviation  # noqa: E402
from lod.temporal.terrain import TerrainHierarchy  # noqa: E402
from lod.view import Camera  # noqa: E402
from sim.terrain import Terrain  # noqa: E402


def camera_path(terrain: Terrain, frames: int):
    """A low fly-through: an ellipse over the terrain, 25 m above the ground,
    looking ahead and slightly down, with speed varying along the way."""
    cams = []
    cx = terrain.origin[0] + 0.5 * terrain.size[0]
    cz = terrain.origin[2] + 0.5 * terrain.size[1]
    rx, rz = 0.3 * terrain.size[0], 0.25 * terrain.size[1]
    for f in range(frames):
        a = 2 * math.pi * (f / 360.0 + 0.15 * math.sin(f / 40.0) / 6.0)
        a2 = a + 0.08
        p = np.array([cx + rx * math.cos(a), 0.0, cz + rz * math.sin(a)])
        q = np.array([cx + rx * math.cos(a2), 0.0, cz + rz * math.sin(a2)])
        p[1] = float(terrain.height(p[0], p[2])) + 25.0
        q[1] = float(terrain.height(q[0], q[2])) + 5.0
        cams.append(Camera.look_at(p, q, fov_y=60.0, near=0.5, far=2000.0))
    return cams


def run(scene: str, frames: int, n: int, tau: float, size) -> None:
    with open(scene, "rb") as fh:
        table = tomllib.load(fh).get("terrain", {})
    terrain = Terrain.from_config(table, str(Path(scene).parent))
    t0 = time.perf_counter()
    hier = TerrainHierarchy(terrain)
    build = time.perf_counter() - t0
    cams = camera_path(terrain, frames)
    full_y = hier.positions[:, 1]
    print(f"# terrain of {scene}: {terrain.nx} x {terrain.nz} samples, grid {hier.n_side}^2, "
          f"{hier.n_full_triangles} full-resolution triangles, hierarchy built in {build:.2f} s "
          f"(incl. JIT on first run)")
    print(f"# {frames} frames at {size[0]}x{size[1]}, tau = {tau} px, n = {n}")
    hier.select(cams[0], size, tau)  # warm the kernels

    rows = []
    t0 = time.perf_counter()
    full_mesh = hier.full_mesh()
    t_full = time.perf_counter() - t0
    rows.append(("full resolution", hier.n_full_triangles, t_full * 1e3 / frames, 0, 0.0, 0.0, 0.0, 0.0))

    for label, nn in (("per-frame selection", 1), (f"keyframed n={n}", n)):
        lod = TemporalTerrainLOD(hier, size, n=nn, tau=tau, mode="delayed")
        tris, times, err, flick = [], [], [], []
        prev = None
        for cam in cams:
            t0 = time.perf_counter()
            fr = lod.frame(cam)
            mesh = fr.mesh()
            times.append(time.perf_counter() - t0)
            tris.append(mesh.n_triangles)
            err.append(pixel_deviation(hier, full_y, fr.grid_heights, fr.camera, size))
            if prev is not None:
                flick.append(pixel_deviation(hier, fr.grid_heights, prev, fr.camera, size))
            prev = fr.grid_heights
        rows.append((label, float(np.mean(tris)), 1e3 * float(np.mean(times)), lod.n_selections,
                     float(np.mean(err)), float(np.max(err)), float(np.mean(flick)), float(np.max(flick))))
    print()
    print("| method | triangles/frame | LOD ms/frame | selections | err mean px | err max px "
          "| flicker mean px | flicker max px |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r[0]} | {r[1]:.0f} | {r[2]:.2f} | {r[3]} | {r[4]:.3f} | {r[5]:.3f} | {r[6]:.3f} | {r[7]:.3f} |")
    print(f"\n(full resolution: {full_mesh.n_triangles} triangles, mesh built once, "
          f"{t_full * 1e3:.1f} ms in all)")

    print("\n| extrapolation mode | err_inter mean/max px | err_view mean/max px "
          "| err_extra mean/max px | delay s |")
    print("|---|---:|---:|---:|---:|")
    for mode in TEMPORAL_MODES:
        lod = TemporalTerrainLOD(hier, size, n=n, tau=tau, mode=mode, measure_errors=True)
        fr = [lod.frame(c) for c in cams][2 * n:]  # skip the start-up intervals
        ei = [f.err_inter for f in fr]
        ev = [f.err_view for f in fr]
        ee = [f.err_extra for f in fr]
        print(f"| {mode} | {np.mean(ei):.3f} / {np.max(ei):.3f} | {np.mean(ev):.3f} / {np.max(ev):.3f} "
              f"| {np.mean(ee):.3f} / {np.max(ee):.3f} | {max(f.delay for f in fr):.3f} |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=str(Path(__file__).resolve().parents[1] / "scenes" / "horses.toml"))
    ap.add_argument("--frames", type=int, default=96)
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--tau", type=float, default=1.0)
    ap.add_argument("--size", type=int, nargs=2, default=[1280, 720])
    a = ap.parse_args(argv)
    run(a.scene, a.frames, a.n, a.tau, tuple(a.size))


if __name__ == "__main__":
    main()
