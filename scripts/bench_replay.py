"""Benchmark: the replay step of a large recorded crowd (issue 47, item 2; ``sim.replay``).

    python scripts/bench_replay.py [--people 1000 10000 100000 1000000] [--frames 30] [--md scripts/bench_replay.md]

A synthetic recording per size: N people on a square grid 2 m apart, each walking a straight line at 1-1.4 m/s in
its own direction for the whole 60 s, recorded at 1 fps (61 rows each, as Pathfinder exports; 61 M rows at a
million), built as columns (``sim.replay.from_columns``: no text file, no PedPy) and stored in the replay cache
(``sim.replay.cache``, in a temporary ``CROWD_CACHE_DIR``) by one process, as a scene's first run stores the file it
parsed. A second process replays it as a later run does: the entry opened (``sim.replay.recording.cached``: the
person-major columns memory-mapped, the frame-major rows streamed), its placement's agents (the people at the
first frame), the effect ``replay`` alone in a world stepped at 30 fps without drawing. Printed per size: the rows,
the median and slowest replay step over ``--frames`` frames after 3 warm-up frames, and the replaying process's
peak RSS (``ru_maxrss``). The issue's targets at a million: the step at most 20 ms, peak memory at most 500 MB above
a 1,000-person run. ``--in-memory`` replays the recording built in the same process instead (no cache: the
recording's rows all in memory, the before of issue 47's item 2).
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
#: seconds recorded, recorded frames per second, scene frames per second
SECONDS, RATE, FPS = 60, 1.0, 30.0
#: what the table replaced, kept under it in the .md
BEFORE = ("Before the frame-major stream (`sim/replay/frames.py`), the recording person-major and in memory, "
          "each person's rows found from the frame before (row cursors), same recordings (2026-12-06): "
          "1,000 people 0.1 ms a step and 160 MB peak; 100,000 3.0 ms, 735 MB; 1,000,000 63.7 ms (slowest "
          "82.4), 6,426 MB (6,266 above 1,000 people). Before the row cursors, a search of every person's rows "
          "each frame: 100,000 people 149 ms a step.")


def recording(n: int):
    """The synthetic recording of ``n`` people (module docstring)."""
    from sim.replay import from_columns

    side = int(np.ceil(np.sqrt(n)))
    rng = np.random.default_rng(7)
    i = np.arange(n)
    x0, y0 = 2.0 * (i % side), 2.0 * (i // side)
    ang = rng.uniform(-np.pi, np.pi, n)
    speed = rng.uniform(1.0, 1.4, n)
    t = np.arange(int(SECONDS * RATE) + 1) / RATE
    ids = np.repeat(i, t.shape[0])
    frames = np.tile(np.arange(t.shape[0], dtype=np.float64), n)
    tt = np.tile(t, n)
    xy = np.stack([np.repeat(x0, t.shape[0]) + np.repeat(np.cos(ang) * speed, t.shape[0]) * tt,
                   np.repeat(y0, t.shape[0]) + np.repeat(np.sin(ang) * speed, t.shape[0]) * tt], axis=1)
    return from_columns(ids, frames, xy, RATE, source=f"synthetic-{n}")


def entry_key(n: int) -> str:
    """The cache key the synthetic recording of ``n`` people is stored under."""
    return hashlib.sha256(f"bench_replay {n} {SECONDS} {RATE}".encode()).hexdigest()


def store(n: int) -> dict:
    """Build the recording of ``n`` people and store its cache entry (this process's memory is not measured)."""
    from sim.replay import cache

    t0 = time.perf_counter()
    rec = recording(n)
    cache.save(entry_key(n), rec)
    if not (cache.cache_dir() / entry_key(n)).is_dir():
        raise RuntimeError(f"could not store the recording in {cache.cache_dir()}")
    return {"store_s": time.perf_counter() - t0}


def humanoid():
    """The generated humanoid with its walk (the characters of a one-line scene: ``crowd.scene``)."""
    import tempfile

    from crowd.engine import Engine
    from crowd.scene import load_scene

    with tempfile.TemporaryDirectory() as td:
        rows = Path(td) / "one.txt"
        rows.write_text("# framerate: 25 fps\n# id frame x/m y/m z/m\n1\t0\t0\t0\t1.7\n1\t1\t0.05\t0\t1.7\n")
        (Path(td) / "s.toml").write_text(
            'name = "one"\ndt = 0.04\nframes = 1\neffects = ["animation"]\n[[characters]]\nname = "walker"\n'
            'generator = "humanoid"\ntriangles = 600\n[[placement]]\nkind = "trajectories"\n'
            f'character = "walker"\nclip = "walk"\nfile = "{rows}"\n[camera]\nposition = [0.0, 8.0, -6.0]\n'
            'target = [0.0, 0.0, 2.0]\n[render]\nsize = [64, 48]\n')
        eng = Engine(load_scene(Path(td) / "s.toml"), quiet=True)
        ch = eng.world.characters
        clip = list(ch[0].clips).index("walk")
        return ch, clip, float(list(ch[0].clips.values())[clip].duration)


def run_one(n: int, frames: int, in_memory: bool, feet: bool = False) -> dict:
    """One size, in this process: ``{"rows", "median_ms", "max_ms", "peak_mb", "build_s"}`` (and with ``feet``
    the step ``replay_feet``'s median: the people drawn as the generated humanoid, feet planted)."""
    import resource

    import sim.animation
    import sim.replay.effect as effect
    from sim.replay.recording import cached
    from sim.replay.track import Track
    from sim.world import World

    t0 = time.perf_counter()
    rec = recording(n) if in_memory else cached(entry_key(n), f"synthetic-{n}", "txt")
    if rec is None:
        raise RuntimeError("the stored recording is not in the cache")
    characters, clip, duration = humanoid() if feet else ([], 0, 1.1)
    track = Track(recording=rec, choices=np.array([[0, clip, 1.0, 1.0, duration]]), rng=np.random.default_rng(1))
    persons = np.flatnonzero(rec.alive(rec.first_frame))
    state = track.agents(persons, rec.first_frame)
    state.tracks = [(0, state.n, track, persons)]
    world = World(state=state, characters=characters)
    if feet:
        sim.animation.install(world, {})
    effect.install(world, {"dt": 1.0 / FPS})
    build = time.perf_counter() - t0
    times, plant = [], []
    for k in range(3 + frames):
        t = {}
        world.step(1.0 / FPS, 1, t)
        if k >= 3:
            times.append(t["replay"])
            plant.append(t.get("replay_feet", 0.0))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {"people": n, "rows": rec.rows, "median_ms": 1e3 * float(np.median(times)),
            "max_ms": 1e3 * float(np.max(times)), "peak_mb": peak, "build_s": build, "agents": world.state.n,
            "feet_ms": 1e3 * float(np.median(plant))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--people", type=int, nargs="+", default=[1000, 10000, 100000, 1000000])
    ap.add_argument("--frames", type=int, default=30, help="timed frames per size (after 3 warm-up frames)")
    ap.add_argument("--md", type=Path, help="write the table here (atomically)")
    ap.add_argument("--in-memory", action="store_true", help="replay the recording built in memory (no cache)")
    ap.add_argument("--feet", action="store_true", help="draw the people as the generated humanoid with planted "
                    "feet: the step replay_feet (sim.replay.planting) timed beside the replay's")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)  # internal: one size in this process
    ap.add_argument("--store", type=int, help=argparse.SUPPRESS)  # internal: store one size's cache entry
    a = ap.parse_args(argv)
    if a.frames < 1 or any(n < 1 for n in a.people):
        print("bench_replay.py: --frames and every --people must be >= 1", file=sys.stderr)
        return 2
    if a.store:
        print(json.dumps(store(a.store)))
        return 0
    if a.one:
        print(json.dumps(run_one(a.one, a.frames, a.in_memory, a.feet)))
        return 0
    rows = []
    tmp = Path(os.environ.get("TMPDIR") or "/tmp") / f"bench_replay-{os.getpid()}"
    env = dict(os.environ, CROWD_CACHE_DIR=str(tmp))

    def child(*args) -> dict | None:
        p = subprocess.run([sys.executable, __file__, *args], capture_output=True, text=True, env=env)
        if p.returncode:
            print(f"bench_replay.py: {' '.join(args)} failed: {p.stderr.strip().splitlines()[-1:]}", file=sys.stderr)
            return None
        return json.loads(p.stdout.strip().splitlines()[-1])

    try:
        for n in a.people:
            s = {} if a.in_memory else child("--store", str(n))
            r = None if s is None else child("--one", str(n), "--frames", str(a.frames),
                                             *(["--in-memory"] if a.in_memory else []),
                                             *(["--feet"] if a.feet else []))
            if r is None:
                return 1
            shutil.rmtree(tmp, ignore_errors=True)  # (each size's entry on its own: the disk holds one)
            rows.append(dict(r, **s))
            print(f"{n:,} people ({r['rows']:,} rows): replay step median {r['median_ms']:.1f} ms, slowest "
                  f"{r['max_ms']:.1f} ms; peak RSS {r['peak_mb']:.0f} MB; opened in {r['build_s']:.1f} s"
                  + (f"; planted feet {r['feet_ms']:.1f} ms a step" if a.feet else "")
                  + (f" (stored in {s['store_s']:.1f} s)" if s else ""))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if a.md:
        from sim.atomic_io import write_atomic

        base = next((r["peak_mb"] for r in rows if r["people"] == 1000), None)
        lines = ["# Replay step of a large recorded crowd (issue 47, item 2)", "",
                 f"Command: `scripts/bench_replay.py --people {' '.join(map(str, a.people))} --frames {a.frames} "
                 f"{'--feet ' if a.feet else ''}--md {a.md}`. Synthetic recordings, {SECONDS} s at {RATE:g} fps, everyone recorded throughout, "
                 f"replayed at {FPS:g} fps with no drawing (module docstring). Targets at a million: step <= 20 ms, "
                 "peak memory <= 500 MB above 1,000 people.", "",
                 "| people | rows | replay step median ms | slowest ms | peak RSS MB | above 1,000 people MB |"
                 + (" planted feet median ms |" if a.feet else ""),
                 "| ---: | ---: | ---: | ---: | ---: | ---: |" + (" ---: |" if a.feet else "")]
        above = ["" if base is None else f"{r['peak_mb'] - base:.0f}" for r in rows]
        lines += [f"| {r['people']:,} | {r['rows']:,} | {r['median_ms']:.1f} | {r['max_ms']:.1f} | {r['peak_mb']:.0f} | "
                  f"{d} |" + (f" {r['feet_ms']:.1f} |" if a.feet else "") for r, d in zip(rows, above)]
        if a.feet:
            lines += ["", "With `--feet` the people are the generated humanoid walking (600 triangles) with feet planted "
                      "(`sim/replay/planting.py`): the world also runs the effect `animation` and the step "
                      "`replay_feet`, timed on its own in the last column (not part of the replay step)."]
        if not a.in_memory:
            lines += ["", BEFORE]
        write_atomic(a.md, "\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
