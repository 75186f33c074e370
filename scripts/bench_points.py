"""Benchmark of the point-hierarchy LOD mode (Wand & Straßer 2002; lod/points/mode.py, render/points/draw.py).

Prints:

1. splat throughput: a grid of instances of a 6,396-triangle procedural
   humanoid (baked to keyframes) far enough that the octree traversal selects
   mostly points; the same DrawList is drawn with the compute-shader splat and
   with the GL_POINTS reference in the same run, frames interleaved (median
   over N frames, ``ctx.finish`` inside the clock). Points/s of both and their ratio
   (target >= 5x).
2. build time per keyframe pair (one segment octree, no cache) of a
   30,000-triangle humanoid with 3 time intervals and with 1 (paper: 20-25 s
   on a 2 GHz Pentium 4; target <= 3 s).
3. (``--scenes``) in-process runs of the scenes (``crowd.engine.Engine``, mode
   "points"; frame 0 is a warm-up and not counted):

   * ``grid`` (90,000 instances, hierarchical instantiation §3.6) at 640x480
     and 1280x720, splat 2, from the scene camera's first view: frame time
     (select + draw, median), its ratio to the same view of a 1,000-instance
     grid (same blocks, fewer of them: output sensitivity, target <= 2x) and,
     at 640x480, to mode "none" (one frame: full detail is slow);
   * the data structure size in MB (every point rep: the characters' segment
     octrees and the super-hierarchies; paper: 123 MB for grid);
   * (``--complexity``) the same grid with 4x the triangles per character
     (§6: rendering time independent of the input meshes' complexity);
   * the paper's Tables 1 and 2: frame time, points and triangles drawn at
     splat 1, 2, 3 for poser4, horses, stadium and grid at 640x480, median over
     frames at camera times spread over each scene's camera path, beside the
     paper's numbers.

Run:  .venv/bin/python scripts/bench_points.py [--size 1280x720] [--frames 3] [--instances 400]
      [--scenes] [--table-frames 3] [--grid-frames 3] [--grid-time 0] [--skip-build] [--skip-splat] [--skip-none]
      [--complexity]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lod.points import mode as pm  # noqa: E402
from lod.points.octree import build_hierarchy  # noqa: E402
from lod.view import Camera  # noqa: E402
from render.renderer import Renderer  # noqa: E402
from sim.procedural import humanoid  # noqa: E402
from sim.state import CrowdState  # noqa: E402


def splat_throughput(size, frames, instances, splat, cache):
    ch = humanoid(6396, seed=41)
    reps, sel = pm.build([ch], ["poser"], [30], {"splat_size": splat, "keyframes": 9}, cache=cache,
                         progress=lambda it, d: it)
    side = int(np.ceil(np.sqrt(instances)))
    st = CrowdState.empty(instances)
    rng = np.random.default_rng(1)
    g = np.arange(instances)
    st.position[:, 0] = (g % side - side / 2) * 1.5
    st.position[:, 2] = -(g // side) * 1.5
    st.heading[:] = rng.uniform(0, 2 * np.pi, instances)
    st.anim_time[:] = rng.uniform(0, 2, instances)
    cam = Camera.look_at((0.0, 0.4 * side, 0.9 * side + 10.0), (0.0, 0.0, -0.5 * side * 1.5), fov_y=50.0)
    r = Renderer(size)
    r.upload(reps[0])
    dl = sel.select(st, cam, size)
    out = {"points": dl.stats["points"], "triangles": dl.stats["triangles"]}
    # the triangles' share, drawn the same way in both paths, is measured alone
    tri_only = [type(b)(**{**b.__dict__, "point_jobs": np.zeros((0, 3), np.int64)}) for b in dl.batches]
    dl2 = type(dl)(dl.origin, dl.view, dl.proj, dl.size, tri_only, dl.stats)
    runs = {"compute": (dl, "compute"), "gl_points": (dl, "gl_points"), "triangles_only": (dl2, "compute")}
    times = {k: [] for k in runs}
    for it in range(frames + 1):  # interleaved, so all three see the same machine load; first is warm-up
        for k, (d, path) in runs.items():
            r.drawer("points").path = path
            t0 = time.perf_counter()
            r.draw(d)  # ends with ctx.finish
            if it:
                times[k].append(time.perf_counter() - t0)
    out.update({k: statistics.median(v) for k, v in times.items()})
    r.release()
    return out


def build_time(triangles, intervals):
    from sim.keyframes import bake_skinned

    ch = humanoid(triangles, seed=3)
    anim = bake_skinned(ch, "walk", 9)
    kf = pm.build_keyframed_rep(pm.keyframed_character(ch, 9))
    arrays = pm.segment_arrays(kf, 0)
    t0 = time.perf_counter()
    h = build_hierarchy(*arrays, intervals=intervals, progress=False)
    dt = time.perf_counter() - t0
    del anim
    return dt, int(arrays[2].shape[0]), h.n_points, h.n_nodes, h.nbytes


#: the paper's Table 1 (rendering time, s, at splat 1/2/3; size MB) and Table 2 (thousands of points / triangles)
PAPER = {
    "poser4": {"time": (0.018, 0.016, 0.013), "mb": 97, "prims": None},
    "horses": {"time": (0.738, 0.319, 0.202), "mb": 208, "prims": ((1608, 715), (645, 195), (316, 95))},
    "stadium": {"time": (1.036, 0.373, 0.188), "mb": 302, "prims": ((2667, 860), (1030, 298), (527, 137))},
    "grid": {"time": (0.861, 0.294, 0.135), "mb": 123, "prims": ((2552, 398), (850, 84), (379, 24))},
}

#: the 1,000-instance grid: each of the 4 trees a 10 x 5 block replicated 5 x 1 (4 x 250 instances)
GRID_1000 = (('{ layout = "grid", nx = 10, nz = 10, spacing = [4.0, 4.0], phase_step = 0.11 }',
              '{ layout = "grid", nx = 10, nz = 5, spacing = [4.0, 4.0], phase_step = 0.11 }'),
             ('{ layout = "grid", nx = 15, nz = 15, spacing = [40.0, 40.0], phase_step = 0.37 }',
              '{ layout = "grid", nx = 5, nz = 1, spacing = [40.0, 40.0], phase_step = 0.37 }'))


def make_engine(name, mode, size, splat=2, edits=()):
    """An Engine of ``scenes/<name>.toml`` in LOD ``mode`` at ``size`` (text ``edits`` applied first)."""
    import dataclasses

    from crowd.engine import Engine
    from crowd.scene import load_scene

    text = (ROOT / "scenes" / f"{name}.toml").read_text()
    for a, b in edits:
        if a not in text:
            raise SystemExit(f"bench_points: scenes/{name}.toml no longer holds {a!r}; update GRID_1000")
        text = text.replace(a, b)
    import shutil

    tmp = Path(tempfile.mkdtemp(prefix="bench_points_")) / f"{name}.toml"
    try:
        tmp.write_text(text)
        sc = load_scene(tmp)
        params = (("splat_size", int(splat)),) if mode == "points" else ()
        sc = dataclasses.replace(sc, lod_mode=mode, lod_params=params)
        return Engine(sc, overrides={"size": size}, quiet=True)  # the engine has read everything it needs
    finally:
        shutil.rmtree(tmp.parent, ignore_errors=True)


def run_frames(eng, size, times, splat=None):
    """Per camera time: one simulation step, then select and draw (timed).
    Returns a list of dicts (select, draw, total seconds; points, triangles, instances)."""
    r = eng._open_renderer()
    if splat is not None:
        eng.settings.splat_size = float(splat)
    out = []
    for t in times:
        eng.step()
        cam = eng.camera_at(t)
        t0 = time.perf_counter()
        dl = eng.select(cam, size)
        t1 = time.perf_counter()
        r.draw(dl)
        r.read_pixels()  # the frame is finished
        t2 = time.perf_counter()
        st = dl.stats
        out.append({"select": t1 - t0, "draw": t2 - t1, "total": t2 - t0, "points": int(st.get("points", 0)),
                    "triangles": int(st.get("triangles", 0)), "instances": int(st.get("instances", 0)),
                    "super_nodes": int(st.get("super_nodes", 0))})
    return out


def med(rows, key):
    return statistics.median(r[key] for r in rows)


def data_mb(eng):
    return sum(int(getattr(r, "nbytes", 0)) for r in eng.reps if getattr(r, "kind", "") == "points") / 1e6


def played_mb(eng):
    """MB of the point reps if only the clips the scene's agents play got point
    hierarchies (``lod.points.mode.build(clips=...)``; the other segments as
    one-node triangle hierarchies), super-hierarchies included."""
    import numpy as np

    from lod.points.mode import played_segments, segment_arrays, triangle_hierarchy

    st = eng.plan.state
    keys = {f"points:{c.name}": i for i, c in enumerate(eng.scene.characters)}
    total = 0
    for r in eng.reps:
        if getattr(r, "kind", "") != "points":
            continue
        ci = keys.get(r.key)
        if ci is None:  # a super-hierarchy (§3.6)
            total += r.nbytes
            continue
        clips = np.unique(np.asarray(st.clip)[np.asarray(st.character) == ci]).tolist()
        played = played_segments(r.keyframed, clips)
        for s, h in enumerate(r.hierarchies):
            total += h.nbytes if played[s] else triangle_hierarchy(*segment_arrays(r.keyframed, s)[:3]).nbytes
    return total / 1e6


def camera_times(eng, n):
    keys = eng.scene.camera.keys if hasattr(eng.scene, "camera") else None
    try:
        t_end = max(float(k.time) for k in keys)
    except Exception:  # no key frames: a fixed camera
        t_end = 0.0
    return [t_end * (i + 0.5) / n for i in range(n)] if t_end > 0 else [0.0] * n


def interleaved_frames(engines: dict, size, frames: int, cam_time: float = 0.0) -> dict:
    """label -> ``frames`` rows of :func:`run_frames` at camera time ``cam_time``, the
    engines' frames taken in turn (so all see the same machine load) after
    one warm-up frame each."""
    rows = {label: [] for label in engines}
    for it in range(frames + 1):
        for label, eng in engines.items():
            row = run_frames(eng, size, [float(cam_time)])[0]
            if it:
                rows[label].append(row)
    return rows


def grid_section(frames, with_none=True, cam_time: float = 0.0):
    """Frame times of the 90,000- and the 1,000-instance grid from the same
    view (the scene's camera at ``cam_time``: 0 = the overview, 8 = the last key,
    3 m above the ground inside the grid), their frames interleaved (both
    engines open at once) so that both see the same machine load; median over
    ``frames`` frames after a warm-up."""
    print(f"\n== grid: output sensitivity (camera at t = {cam_time:g} s, splat 2; frames of both grids interleaved) ==")
    res = {}
    for size in ((640, 480), (1280, 720)):
        t0 = time.perf_counter()
        from render.context import create_context

        ctx = create_context()  # one GL context for both renderers
        with make_engine("grid", "points", size, 2) as big, make_engine("grid", "points", size, 2, GRID_1000) as small:
            big.open_renderer(size, ctx=ctx)
            small.open_renderer(size, ctx=ctx)
            built = time.perf_counter() - t0
            if size == (640, 480):
                res["mb"] = data_mb(big)
                res["played_mb"] = played_mb(big)
                res["n_reps"] = sum(1 for r in big.reps if getattr(r, "kind", "") == "points")
            rows = interleaved_frames({"90,000": big, "1,000": small}, size, frames, cam_time)
        ctx.release()
        for label in ("90,000", "1,000"):
            r_ = rows[label]
            res[(size, label)] = r_
            print(f"  {size[0]}x{size[1]} {label:>6} instances: frame {med(r_, 'total') * 1e3:7.1f} ms "
                  f"(select {med(r_, 'select') * 1e3:.1f}, draw {med(r_, 'draw') * 1e3:.1f}), "
                  f"{med(r_, 'points'):,.0f} points, {med(r_, 'triangles'):,.0f} triangles, "
                  f"{med(r_, 'super_nodes'):,.0f} super nodes, {med(r_, 'instances'):,.0f} instances drawn")
        a, b = rows["90,000"], rows["1,000"]
        ratios = [x["total"] / y["total"] for x, y in zip(a, b)]
        print(f"  {size[0]}x{size[1]}: 90,000 / 1,000 instances = {med(a, 'total') / med(b, 'total'):.2f}x "
              f"(per interleaved pair: {', '.join(f'{v:.2f}' for v in ratios)}; target <= 2x); "
              f"engines set up in {built:.0f} s")
        # what grows with what: the selection with the instances (hierarchical instantiation keeps
        # it sub-linear), the drawing with the points (the output: pixels covered)
        print(f"  {size[0]}x{size[1]}: selection 90,000 / 1,000 = {med(a, 'select') / med(b, 'select'):.2f}x "
              f"for 90x the instances; points 90,000 / 1,000 = {med(a, 'points') / max(med(b, 'points'), 1):.0f}x, "
              f"draw {med(a, 'draw') / med(b, 'draw'):.2f}x")
    if with_none:
        with make_engine("grid", "none", (640, 480)) as eng:
            rows = run_frames(eng, (640, 480), [0.0, 0.0])[1:]
        nt = med(rows, "total")
        print(f"  640x480 mode none (full detail, 1 frame): {nt:.2f} s, {med(rows, 'triangles'):,.0f} triangles; "
              f"points / none = 1 / {nt / med(res[((640, 480), '90,000')], 'total'):.0f}")
    print(f"  data structure: {res['mb']:.0f} MB in {res['n_reps']} point reps (paper: 123 MB); "
          f"{res['played_mb']:.0f} MB with point hierarchies for the played clips only")
    return res


#: the grid's characters with 4x the triangles (2.3 G triangles in all)
GRID_DETAILED = (("triangles = 6396", "triangles = 25584"),)


def complexity_section(frames, sizes=((640, 480), (1280, 720))):
    """§6 "the rendering time is independent of the complexity of the input
    meshes": the 90,000-instance grid with its characters at 6,396 and at
    25,584 triangles (576 M and 2.3 G triangles), same view, frames of both
    interleaved; median frame time and their ratio."""
    print("\n== grid: model complexity (characters of 6,396 vs 25,584 triangles, 90,000 instances, splat 2) ==")
    from render.context import create_context

    for size in sizes:
        t0 = time.perf_counter()
        ctx = create_context()
        with make_engine("grid", "points", size, 2) as base, make_engine("grid", "points", size, 2,
                                                                          GRID_DETAILED) as fine:
            base.open_renderer(size, ctx=ctx)
            fine.open_renderer(size, ctx=ctx)
            built = time.perf_counter() - t0
            rows = interleaved_frames({"6,396": base, "25,584": fine}, size, frames)
        ctx.release()
        for label, r_ in rows.items():
            print(f"  {size[0]}x{size[1]} {label:>6}-triangle characters: frame {med(r_, 'total') * 1e3:7.1f} ms "
                  f"(select {med(r_, 'select') * 1e3:.1f}, draw {med(r_, 'draw') * 1e3:.1f}), "
                  f"{med(r_, 'points'):,.0f} points, {med(r_, 'triangles'):,.0f} triangles")
        a, b = rows["25,584"], rows["6,396"]
        pairs = ", ".join("%.2f" % (x["total"] / y["total"]) for x, y in zip(a, b))
        print(f"  {size[0]}x{size[1]}: 4x the triangles per character = {med(a, 'total') / med(b, 'total'):.2f}x "
              f"the frame time (per interleaved pair: {pairs}); engines set up in {built:.0f} s")


def tables_section(frames, size=(640, 480)):
    print(f"\n== Tables 1 and 2 at {size[0]}x{size[1]}: frame time, points / triangles drawn "
          f"(median of {frames} frames over the camera path; paper in brackets) ==")
    lines = []
    for name in ("poser4", "horses", "stadium", "grid"):
        t0 = time.perf_counter()
        with make_engine(name, "points", size, 2) as eng:
            built = time.perf_counter() - t0
            times = camera_times(eng, frames)
            run_frames(eng, size, times[:1], splat=2)  # warm-up
            cells = []
            for splat in (1, 2, 3):
                rows = run_frames(eng, size, times, splat=splat)
                cells.append((med(rows, "total"), med(rows, "points"), med(rows, "triangles")))
            mb = data_mb(eng)
        p = PAPER[name]
        txt = []
        for k, (ft, npt, ntr) in enumerate(cells):
            pp = p["prims"][k] if p["prims"] else None
            ref = f"[{p['time'][k]:.3f} s" + (f", {pp[0]}k / {pp[1]}k]" if pp else "]")
            txt.append(f"splat {k + 1}: {ft:.3f} s, {npt / 1e3:,.0f}k / {ntr / 1e3:,.0f}k {ref}")
        line = f"  {name:8s} {mb:6.0f} MB [{p['mb']} MB]; " + "; ".join(txt) + f" (set-up {built:.0f} s)"
        print(line, flush=True)
        lines.append(line)
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--frames", type=int, default=7)
    ap.add_argument("--instances", type=int, default=400)
    ap.add_argument("--splat", type=int, default=2)
    ap.add_argument("--build-triangles", type=int, default=30000)
    ap.add_argument("--scenes", action="store_true", help="also the grid and Tables 1/2 sections (slow)")
    ap.add_argument("--table-frames", type=int, default=3, help="frames per scene and splat size in the tables")
    ap.add_argument("--grid-frames", type=int, default=3, help="frames per grid run")
    ap.add_argument("--grid-time", type=float, default=0.0,
                    help="camera time of the grid views (0: the overview; 8: inside the grid, 3 m up)")
    ap.add_argument("--skip-build", action="store_true")
    ap.add_argument("--skip-splat", action="store_true")
    ap.add_argument("--skip-tables", action="store_true")
    ap.add_argument("--skip-none", action="store_true", help="no full-detail grid frame (about 2-3 min here)")
    ap.add_argument("--complexity", action="store_true",
                    help="also the grid with 4x the triangles per character (builds its hierarchies once: minutes)")
    a = ap.parse_args(argv)
    size = tuple(int(v) for v in a.size.lower().split("x"))
    cache = pm.HierarchyCache()
    if os.getloadavg()[0] > (os.cpu_count() or 1):
        print(f"note: load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores: timings are inflated")
    if not a.skip_splat:
        s = splat_throughput(size, a.frames, a.instances, a.splat, cache)
        pts = s["points"]
        tc, tg, tt = s["compute"], s["gl_points"], s["triangles_only"]
        print(f"splat throughput at {size[0]}x{size[1]}, splat {a.splat}, {a.instances} instances: "
              f"{pts} points + {s['triangles']} triangles per frame")
        print(f"  frame: compute {tc * 1e3:.1f} ms, GL_POINTS {tg * 1e3:.1f} ms, triangles only {tt * 1e3:.1f} ms")
        pc, pg = tc - tt, tg - tt
        print(f"  points/s (frame minus the triangles-only frame): compute {pts / max(pc, 1e-9) / 1e6:.1f} M, "
              f"GL_POINTS {pts / max(pg, 1e-9) / 1e6:.1f} M, ratio {pg / max(pc, 1e-9):.1f}x (target >= 5x)")
    if not a.skip_build:
        for iv in (3, 1):
            dt, T, P, N, nb = build_time(a.build_triangles, iv)
            print(f"build of one keyframe pair, {T} triangles, {iv} interval(s): {dt:.2f} s "
                  f"({P} points, {N} nodes, {nb / 1e6:.1f} MB; paper 20-25 s with 1 interval; target <= 3 s)")
    if a.scenes:
        grid_section(a.grid_frames, not a.skip_none, a.grid_time)
        if a.complexity:
            complexity_section(a.grid_frames)
        if not a.skip_tables:
            tables_section(a.table_frames)


if __name__ == "__main__":
    main()
