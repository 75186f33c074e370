"""Benchmark: mode auto's selection by the flat path (``lod/auto/flat.py``) against the per-group path
(``AutoSelector.flat = False``) on skinned characters whose points follow the animation (``lod.points.follow``,
the default) or, with ``--animation baked``, on the per-keyframe-pair octrees.

The scene is ``scenes/million.toml`` (a generated 5,000-triangle humanoid, boids over 2 x 2 km, its camera) with
``--side`` x ``--side`` agents on the same field (the spacing widened: 447 gives about 200 K agents); ``--near``
puts the camera at street level (near agents in triangles or clusters: a mixed plan). Auto's own path runs every
frame (no single-mode delegation of a held plan, :mod:`lod.auto.delegate`). The same frame is selected by both
paths, interleaved (a ratio measured in one run survives the load); medians of wall and process CPU time (all
threads). The load average before and after is printed: the machine is shared.

Run:  .venv/bin/python scripts/bench_flat_follow.py [--side 447] [--repeats 7] [--animation follow|baked] [--near]
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--side", type=int, default=447, help="agents per row and column (447: ~200 K)")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--animation", choices=("follow", "baked"), default="follow")
    ap.add_argument("--near", action="store_true", help="a street-level camera (mixed plans)")
    a = ap.parse_args(argv)

    import numba
    import numpy as np

    from crowd.engine import Engine
    from crowd.scene import load_scene
    from lod.auto import flat
    from lod.auto.candidates import PointsCandidate
    from lod.auto.delegate import Delegates
    from lod.points import mode as pm
    from lod.view import Camera

    if a.animation == "baked":  # every character's points on the per-keyframe-pair octrees
        pm.animation_path = lambda ch, p: ("baked", "bench_flat_follow.py --animation baked")
    scene = load_scene(str(ROOT / "scenes" / "million.toml"))
    sp = 2000.0 / a.side
    pl = tuple(dataclasses.replace(p, params=dict(p.params, rows=a.side, cols=a.side, spacing=[sp, sp]))
               for p in scene.placements)
    scene = dataclasses.replace(scene, placements=pl)
    print("load:", os.getloadavg(), "numba threads:", numba.get_num_threads())
    with Engine(scene, quiet=True) as eng:
        eng.step()
        sel = eng.selector
        sel.delegates = Delegates({})
        follow = [getattr(r, "follow", False) for c in sel.candidates if isinstance(c, PointsCandidate)
                  for r in c.by_char.values()]
        cam = eng.camera_at(eng.world.time)
        if a.near:
            cam = Camera.look_at((0.0, 12.0, 1000.0), (0.0, 0.0, 900.0), fov_y=50.0, near=1.0, far=5000.0)
        size = scene.render.size
        kinds = []
        groups = flat.groups

        def counted(*args, **kw):
            out = groups(*args, **kw)
            kinds.append(type(out).__name__)
            return out

        flat.groups = counted
        times = {True: [], False: []}
        lists = {}
        for f in (True, False):  # compile / warm
            sel.flat = f
            sel.select(eng.world.state, cam, size)
        for _ in range(a.repeats):
            for f in (True, False):
                sel.flat = f
                t, c = time.perf_counter(), time.process_time()
                lists[f] = sel.select(eng.world.state, cam, size)
                times[f].append((time.perf_counter() - t, time.process_time() - c))
        flat.groups = groups
        x, y = lists[True], lists[False]
        same = [(b.rep, b.part, b.level) for b in x.batches] == [(b.rep, b.part, b.level) for b in y.batches] and \
            all(np.array_equal(b.instance_ids, c.instance_ids) for b, c in zip(x.batches, y.batches))
        print(f"agents {eng.world.state.n}, animation {a.animation} (follow reps: {follow}), flat.groups gave "
              f"{sorted(set(kinds))}, plan {x.stats['auto']['plan']}, {x.stats['auto']['representations']}")
    for f, v in times.items():
        print(f"{'flat' if f else 'per-group'}: wall {1e3 * statistics.median(w for w, _ in v):.0f} ms, "
              f"cpu {1e3 * statistics.median(c for _, c in v):.0f} ms (wall: {[round(1e3 * w) for w, _ in v]})")
    print("same draw lists:", bool(same), " load:", os.getloadavg())
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
