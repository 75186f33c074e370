"""Benchmark: how far the stance foot of a replayed person slides per step (issue 47, item 3; ``sim.replay.feet``).

    python scripts/bench_foot_drift.py [--md scripts/bench_foot_drift.md]

Replays each recording of ../shared/data/pedestrian (the bottleneck experiment, the JuPedSim and Vadere runs; a
missing one is left out and said so) and a straight synthetic walk at 1.2 m/s as the generated humanoid walking,
with no drawing, and measures every step's drift of the stance foot from the skinned feet (of the drawn bodies):
per recording and ``feet`` setting (``planted``, the default, ``sim.replay.planting``; ``recorded``) the steps
measured, the median, 95th percentile and largest drift, and the share of steps above the issue's 5 cm. The
figures are of the simulation (no timing), so the machine's load does not change them.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
DATA = ROOT.parent / "shared" / "data" / "pedestrian"
#: the issue's bound on the drift of a step, metres
TARGET = 0.05

SCENE = """name = "foot_drift"
seed = 5
dt = {dt}
frames = {frames}
effects = ["animation"]

[[characters]]
name = "pedestrian"
generator = "humanoid"
triangles = 1500
seed = 231

[[placement]]
kind = "trajectories"
character = "pedestrian"
clip = "walk"
file = "{file}"
{extra}
[camera]
position = [0.0, 8.0, -6.0]
target = [0.0, 0.0, 2.0]

[render]
size = [64, 36]
"""

CASES = [  # name, file under DATA (None: synthetic), extra keys
    ("straight walk, 1.2 m/s (synthetic)", None, ""),
    ("bottleneck experiment (PeTrack, 75 people)", "bottleneck/040_c_56_h-.txt", ""),
    ("JuPedSim run (30 agents)", "jupedsim/trajectories.sqlite", ""),
    ("Vadere run (20 agents)", "vadere/vadere_postvis.traj", "frame_rate = 24.0\n"),
]


def _straight(folder: Path) -> Path:
    p = folder / "straight.txt"
    lines = ["# framerate: 25 fps", "# id frame x/m y/m z/m"]
    lines += [f"{i}\t{f}\t{0.048 * f:.4f}\t{1.5 * i:.4f}\t1.7" for i in range(4) for f in range(300)]
    p.write_text("\n".join(lines) + "\n")
    return p


#: the placement's feet settings measured
FEET = ("planted", "recorded")
#: a step whose mean recorded ground speed is at least this (m/s) is walking; under SLOW, creeping (a jam)
WALKING, SLOW = 0.4, 0.2


def measure(file: Path, extra: str, folder: Path) -> dict:
    from crowd.engine import Engine
    from crowd.scene import load_scene
    from sim.replay import load
    from sim.replay.feet import replay_steps

    kw = {"frame_rate": 24.0} if "frame_rate" in extra else {}
    rec = load(file, **kw)
    frames = int(rec.last_frame - rec.first_frame) + 1
    scene = folder / "scene.toml"
    scene.write_text(SCENE.format(dt=1.0 / rec.frame_rate, frames=frames, file=file, extra=extra))
    t0 = time.perf_counter()
    steps = replay_steps(Engine(load_scene(scene), quiet=True), frames)
    d, v = steps[:, 0], steps[:, 1]
    walking = d[v >= WALKING]
    return {"steps": int(d.shape[0]), "median": float(np.median(d)), "p95": float(np.percentile(d, 95)),
            "max": float(d.max()), "over": float((d > TARGET).mean()), "seconds": time.perf_counter() - t0,
            "walking": int(walking.shape[0]),
            "walking_over": float((walking > TARGET).mean()) if walking.shape[0] else 0.0,
            "slow": int((v < SLOW).sum()), "slow_over": float((d[v < SLOW] > TARGET).mean()) if (v < SLOW).any()
            else 0.0}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--md", type=Path, help="write the table here (atomically)")
    a = ap.parse_args(argv)
    rows, notes = [], []
    with tempfile.TemporaryDirectory() as td:
        for name, rel, extra in CASES:
            file = _straight(Path(td)) if rel is None else DATA / rel
            if not file.is_file():
                notes.append(f"{name}: no data at {file}, left out")
                print(f"# {notes[-1]}")
                continue
            for feet in FEET:
                r = measure(file, extra + f'feet = "{feet}"\n', Path(td))
                rows.append((name, feet, r))
                print(f"{name}, feet {feet}: {r['steps']} steps, drift median {100 * r['median']:.1f} cm, 95th "
                      f"percentile {100 * r['p95']:.1f} cm, max {100 * r['max']:.1f} cm, {100 * r['over']:.0f} % "
                      f"above {100 * TARGET:.0f} cm ({r['seconds']:.1f} s)")
    if a.md:
        from sim.atomic_io import write_atomic

        lines = ["# Foot drift of replayed people (issue 47, item 3)", "",
                 f"Command: `scripts/bench_foot_drift.py --md {a.md}`. The stance foot's drift per step, measured "
                 "from the generated humanoid's skinned feet (`sim/replay/feet.py`) of the drawn bodies; feet "
                 "`planted` (the default, `sim/replay/planting.py`) or `recorded`; the issue asks for at most "
                 f"{100 * TARGET:.0f} "
                 f"cm. Walking: steps at a mean recorded ground speed of at least {WALKING:g} m/s; creeping: under "
                 f"{SLOW:g} m/s (a jam).", "",
                 "| recording | feet | steps | median cm | 95th percentile cm | max cm | steps above 5 cm | walking "
                 "steps above 5 cm | creeping steps above 5 cm |",
                 "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
        lines += [f"| {n} | {feet} | {r['steps']:,} | {100 * r['median']:.1f} | {100 * r['p95']:.1f} | "
                  f"{100 * r['max']:.1f} | {100 * r['over']:.0f} % | {100 * r['walking_over']:.0f} % of "
                  f"{r['walking']} | {100 * r['slow_over']:.0f} % of {r['slow']} |" for n, feet, r in rows]
        lines += [""] + [f"- {n}" for n in notes]
        write_atomic(a.md, "\n".join(lines).rstrip() + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
