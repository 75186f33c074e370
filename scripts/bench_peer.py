"""Benchmark: our frame time in every LOD mode against a peer engine, Panda3D, on the same crowd (issue 21).

The scenario (both sides, computed here once and handed to the peer): N copies of a model on a square
grid (``ceil(sqrt(N))`` columns, centred on the origin) spaced 1.5x the model's largest rest extent;
the camera above the middle of the grid's near edge at half the grid's width W up and 0.6 W back,
looking at the grid's centre; vertical field of view 50 degrees; 1280x720; every copy plays the
model's first clip from time 0, heading 0. Ours: ``crowd.engine.Engine`` on a generated scene file
(Mesa llvmpipe through EGL); a frame is simulate + select + draw + ``ctx.finish``. The peer: Panda3D
(PyPI ``panda3d`` + ``panda3d-gltf``, one ``Actor`` per copy, through its own OpenGL renderer,
offscreen; ``scripts/peer_panda3d.py``) in its own interpreter, a subprocess that prints JSON; a
frame is ``taskMgr.step()`` + ``glFinish``. Panda3D is a benchmark-only dependency: ``make
bench-peers`` puts it in ``.venv-peers`` (``--peers-python``, or the environment variable
``CROWD_PEERS_PYTHON``, names another interpreter).

Models: ``../shared/assets`` Fox (576 triangles) and CesiumMan (skipped with a note when absent), and
two generated 60 K-triangle humanoids (``scripts/peer_models.py``: 4 influences per vertex; 1
influence split into 59 primitives). The machine is shared: each round runs the peer, then each of
our modes (in an order rotated every round); medians are over all timed frames of all rounds, and
"paired" is the median over rounds of (peer median / ours median) in that round.

Run:  .venv/bin/python scripts/bench_peer.py [--models fox cesiumman h4 h1] [--counts N ...]
      [--modes none points clusters triangles auto] [--frames 5] [--warmup 2] [--rounds 2]
      [--peers-python PATH] [--hardware-skinning] [--png DIR] [--out scripts/bench_peer.md]
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

#: LOD modes timed (ours); "none-exact" is mode none with pose sharing off (``[lod] pose_rate = 0``: every copy
#: its own pose, issue 29), the others share poses at the default rate (lod.poses)
MODES = ("none", "none-exact", "points", "clusters", "triangles", "auto")
#: a timed mode -> (LOD mode, pose_rate)
MODE_RATES = {"none-exact": ("none", 0.0)}
#: model name -> default instance counts
DEFAULT_COUNTS = {"fox": [100, 324, 1024], "cesiumman": [100], "h4": [100], "h1": [100]}
#: vertical field of view, degrees
FOV = 50.0
#: grid spacing in largest rest extents
SPACING = 1.5
PEERS_ENV = "CROWD_PEERS_PYTHON"
#: the shared glTF assets: ``../shared/assets`` beside the checkout (a git worktree one level deeper finds it
#: one folder further up)
ASSETS = next((p for p in (ROOT.parent / "shared" / "assets", ROOT.parents[1] / "shared" / "assets") if p.is_dir()),
              ROOT.parent / "shared" / "assets")


def model_paths(models_dir: Path) -> dict:
    """name -> (path or None, description)."""
    out = {"fox": (ASSETS / "Fox.glb", "Fox.glb (shared assets)"),
           "cesiumman": (ASSETS / "CesiumMan.glb", "CesiumMan.glb (shared assets)")}
    for k in ("fox", "cesiumman"):
        if not out[k][0].is_file():
            out[k] = (None, out[k][1] + f": absent from {ASSETS}, skipped")
    from peer_models import write_models

    gen = write_models(models_dir)
    out["h4"] = (gen["humanoid60k-4inf"], "humanoid 60 K triangles, 4 influences (generated)")
    out["h1"] = (gen["humanoid60k-1inf-59prims"], "humanoid 60 K triangles, 1 influence, 59 primitives (generated)")
    return out


def scenario(extent: float, n: int) -> dict:
    """Positions (Y-up), camera and clip planes of ``n`` copies of a model of largest rest extent ``extent``."""
    s = SPACING * extent
    cols = int(math.ceil(math.sqrt(n)))
    rows = int(math.ceil(n / cols))
    i = np.arange(n)
    pos = np.zeros((n, 3))
    pos[:, 0] = (i % cols - (cols - 1) / 2) * s
    pos[:, 2] = (i // cols - (rows - 1) / 2) * s
    width = cols * s
    eye = [0.0, 0.5 * width, 0.5 * rows * s + 0.6 * width]
    return {"positions": pos.tolist(), "eye": eye, "target": [0.0, 0.0, 0.0], "fov": FOV,
            "near": 0.01 * width, "far": 10.0 * width, "width": width, "spacing": s}


def scene_text(model: Path, clip: str, sc: dict, size, phase: str = "zero", bare: bool = False) -> str:
    """The generated scene of our side; ``bare``: no ground plane and no shadows (what the peer draws: the actors
    on the background), else the scene defaults (a ground plane and blob shadows)."""
    extra = '\nground = false\nshadows = "none"' if bare else ""
    pos = ", ".join(f"[{x:.6g}, {y:.6g}, {z:.6g}]" for x, y, z in sc["positions"])
    return f"""name = "bench_peer"
seed = 0
frames = 1000000
effects = ["animation"]

[[characters]]
name = "model"
file = "{model}"

[[placement]]
kind = "list"
character = "model"
clip = "{clip}"
positions = [{pos}]
heading = 0.0
phase = "{phase}"

[camera]
fov = {sc['fov']}
near = {sc['near']:.6g}
far = {sc['far']:.6g}
position = [{sc['eye'][0]:.6g}, {sc['eye'][1]:.6g}, {sc['eye'][2]:.6g}]
target = [0.0, 0.0, 0.0]

[render]
size = [{size[0]}, {size[1]}]{extra}

[lod]
mode = "none"
"""


def run_peer(python: str, model: Path, clip: str, sc: dict, size, frames, warmup, hw, png=None, phases=None) -> dict:
    spec = {"model": str(model), "clip": clip, "positions": sc["positions"], "eye": sc["eye"],
            "target": sc["target"], "fov": sc["fov"], "near": sc["near"], "far": sc["far"], "size": list(size),
            "frames": frames, "warmup": warmup, "hardware_skinning": hw,
            "phases": None if phases is None else [float(x) for x in phases]}
    if png:
        spec["screenshot"] = str(png)
    p = subprocess.run([python, str(ROOT / "scripts" / "peer_panda3d.py")], input=json.dumps(spec),
                       capture_output=True, text=True)
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("{")]
    if p.returncode or not lines:
        raise RuntimeError(f"peer failed (exit {p.returncode}): {p.stderr.strip()[-600:]}")
    return json.loads(lines[-1])


def time_ours(eng, mode: str, frames: int, warmup: int, png=None) -> tuple:
    """(wall seconds, CPU seconds) of each timed frame of ``mode`` (:data:`MODES`)."""
    from lod.poses import KEY_RATE

    base, rate = MODE_RATES.get(mode, (mode, KEY_RATE))
    eng.set_lod_mode(base)
    eng.pose_sharing.rate = rate
    r = eng.renderer
    size = eng.scene.render.size
    wall, cpu = [], []
    for k in range(warmup + frames):
        t0, c0 = time.perf_counter(), time.process_time()
        eng.step()
        cam = eng.camera_at(eng.world.time)
        dl = eng.select(cam, size)
        r.draw(dl, eng.scene.render.background)
        t1, c1 = time.perf_counter(), time.process_time()
        if k >= warmup:
            wall.append(t1 - t0)
            cpu.append(c1 - c0)
    if png:
        from crowd.images import write_png

        write_png(png, r.read_pixels())
    eng.pose_sharing.rate = KEY_RATE
    return wall, cpu


def machine_note() -> str:
    try:
        ps = subprocess.run(["ps", "-eo", "pcpu,comm", "--sort=-pcpu"], capture_output=True, text=True).stdout
        top = [ln.split(None, 1) for ln in ps.splitlines()[1:7]]
        busy = ", ".join(f"{c.strip()} {p}%" for p, c in top if float(p) >= 5.0)
    except (OSError, ValueError):
        busy = "?"
    la = os.getloadavg()
    return f"load average {la[0]:.2f} / {la[1]:.2f} / {la[2]:.2f}; busiest processes: {busy or 'none above 5 %'}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", nargs="+", default=["fox", "cesiumman", "h4", "h1"],
                    choices=["fox", "cesiumman", "h4", "h1"])
    ap.add_argument("--counts", type=int, nargs="+", help="instance counts (default per model: fox 100 324 1024, "
                    "the others 100)")
    ap.add_argument("--modes", nargs="+", default=list(MODES), choices=list(MODES))
    ap.add_argument("--frames", type=int, default=5, help="timed frames per side and round")
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--size", type=int, nargs=2, default=[1280, 720])
    ap.add_argument("--peers-python", default=os.environ.get(PEERS_ENV, str(ROOT / ".venv-peers" / "bin" / "python")),
                    help=f"interpreter with panda3d and panda3d-gltf (default ${PEERS_ENV} or .venv-peers/bin/python)")
    ap.add_argument("--hardware-skinning", action="store_true", help="Panda3D hardware-animated-vertices on")
    ap.add_argument("--phase", choices=("zero", "random"), default="zero",
                    help="every copy from time 0 (default: one shared pose), or each at a random time of its clip "
                         "(the same times on both sides)")
    ap.add_argument("--bare", action="store_true",
                    help="our side without the ground plane and blob shadows (the peer draws neither)")
    ap.add_argument("--models-dir", type=Path, default=ROOT / "out" / "bench_peer" / "models")
    ap.add_argument("--png", type=Path, help="write the last frame of each side here")
    ap.add_argument("--out", type=Path, default=ROOT / "scripts" / "bench_peer.md")
    args = ap.parse_args(argv)
    for k in ("frames", "rounds"):
        if getattr(args, k) < 1:
            print(f"bench_peer.py: --{k}: expected >= 1, got {getattr(args, k)}", file=sys.stderr)
            return 2
    if args.warmup < 0:
        print(f"bench_peer.py: --warmup: expected >= 0, got {args.warmup}", file=sys.stderr)
        return 2
    if not Path(args.peers_python).is_file():
        print(f"bench_peer.py: --peers-python: {args.peers_python} does not exist; run `make bench-peers` or give an "
              f"interpreter with panda3d and panda3d-gltf (option or ${PEERS_ENV})", file=sys.stderr)
        return 2
    sys.path.insert(0, str(ROOT / "scripts"))
    from crowd.engine import Engine
    from crowd.scene import load_scene
    from sim.gltf.load import load_gltf

    size = tuple(args.size)
    paths = model_paths(args.models_dir)
    notes, rows = [], []
    start_note = machine_note()
    gl_line = peer_line = ""
    print(f"# start: {start_note}")
    for mk in args.models:
        path, desc = paths[mk]
        if path is None:
            notes.append(desc)
            print(f"# {desc}")
            continue
        ch = load_gltf(path)
        rest = np.asarray(ch.mesh.positions, np.float64)
        extent = float((rest.max(0) - rest.min(0)).max())
        clip = ch.clip_names()[0] if ch.clip_names() else ""
        tris = int(ch.mesh.n_triangles)
        for n in args.counts or DEFAULT_COUNTS[mk]:
            sc = scenario(extent, n)
            with tempfile.TemporaryDirectory() as td:
                scene_path = Path(td) / "bench_peer.toml"
                scene_path.write_text(scene_text(path.resolve(), clip, sc, size, args.phase, args.bare))
                eng = Engine(load_scene(scene_path), quiet=True)
                phases = eng.world.state.anim_time.copy() if args.phase == "random" else None
                try:
                    eng.open_renderer()
                    for m in args.modes:  # build (or load from the cache) before any timing
                        eng.set_lod_mode(MODE_RATES.get(m, (m,))[0])
                    from render.context import gl_info

                    info = gl_info(eng.renderer.ctx)
                    gl_line = f"{info['GL_RENDERER']} ({info['GL_VERSION']})"
                    peer_t, ours_t, paired = [], {m: [] for m in args.modes}, {m: [] for m in args.modes}
                    peer_c, ours_c = [], {m: [] for m in args.modes}
                    for rd in range(args.rounds):
                        last = rd == args.rounds - 1
                        png = (args.png / f"{mk}_{n}_panda3d.png") if (args.png and last) else None
                        if png:
                            png.parent.mkdir(parents=True, exist_ok=True)
                        pr = run_peer(args.peers_python, path.resolve(), clip, sc, size, args.frames, args.warmup,
                                      args.hardware_skinning, png, phases)
                        peer_line = f"Panda3D {pr['panda3d']} on {pr['renderer']}"
                        peer_t += pr["frames_s"]
                        peer_c += pr["cpu_s"]
                        pm = statistics.median(pr["frames_s"])
                        order = args.modes[rd % len(args.modes):] + args.modes[:rd % len(args.modes)]
                        for m in order:
                            t, c = time_ours(eng, m, args.frames, args.warmup,
                                             (args.png / f"{mk}_{n}_{m}.png") if (args.png and last) else None)
                            ours_t[m] += t
                            ours_c[m] += c
                            paired[m].append(pm / statistics.median(t))
                finally:
                    eng.close()
            peer_med = statistics.median(peer_t)
            row = {"model": mk, "desc": desc, "triangles": tris, "n": n, "peer": peer_med,
                   "ours": {m: statistics.median(v) for m, v in ours_t.items()},
                   "paired": {m: statistics.median(v) for m, v in paired.items()},
                   "peer_cpu": statistics.median(peer_c), "ours_cpu": {m: statistics.median(v) for m, v in ours_c.items()}}
            rows.append(row)
            line = "  ".join(f"{m} {row['ours'][m] * 1e3:.1f} ms ({peer_med / row['ours'][m]:.2f}x, paired "
                             f"{row['paired'][m]:.2f}x; CPU {row['ours_cpu'][m] * 1e3:.1f} ms, "
                             f"{row['peer_cpu'] / row['ours_cpu'][m]:.2f}x)" for m in args.modes)
            print(f"{mk} x{n} ({tris} tri): Panda3D {peer_med * 1e3:.1f} ms (CPU {row['peer_cpu'] * 1e3:.1f} ms) | "
                  f"ours {line}", flush=True)
    end_note = machine_note()
    print(f"# end: {end_note}")
    write_md(args, rows, notes, gl_line, peer_line, start_note, end_note)
    return 0


def write_md(args, rows, notes, gl_line, peer_line, start_note, end_note) -> None:
    from sim.atomic_io import write_atomic

    cmd = "scripts/bench_peer.py " + " ".join(sys.argv[1:]) if sys.argv[0].endswith("bench_peer.py") else "main()"
    modes = args.modes
    head = "| model | triangles | copies | Panda3D ms | " + " | ".join(f"ours {m} ms (x)" for m in modes) + " |"
    sep = "| --- | ---: | ---: | ---: | " + " | ".join("---:" for _ in modes) + " |"
    lines = [head, sep]
    cpu_lines = [head.replace(" ms", " CPU ms"), sep]
    for r in rows:
        cells = " | ".join(f"{r['ours'][m] * 1e3:.1f} ({r['peer'] / r['ours'][m]:.2f}x; {r['paired'][m]:.2f}x)"
                           for m in modes)
        lines.append(f"| {r['desc']} | {r['triangles']:,} | {r['n']:,} | {r['peer'] * 1e3:.1f} | {cells} |")
        cells = " | ".join(f"{r['ours_cpu'][m] * 1e3:.1f} ({r['peer_cpu'] / r['ours_cpu'][m]:.2f}x)" for m in modes)
        cpu_lines.append(f"| {r['desc']} | {r['triangles']:,} | {r['n']:,} | {r['peer_cpu'] * 1e3:.1f} | {cells} |")
    text = f"""# Peer benchmark: ours in every LOD mode against Panda3D (issues 21, 29)

Command: `{cmd}` ({args.rounds} round(s) x {args.frames} timed frames after {args.warmup} warm-up frames per side,
{args.size[0]}x{args.size[1]}; Panda3D hardware-animated-vertices {'on' if args.hardware_skinning else 'off'}; every copy
{'from time 0' if args.phase == 'zero' else 'at a random time of its clip, the same on both sides'}). Our modes share
poses at the default `pose_rate` (the clip's keys; lod.poses), except `none-exact` (`pose_rate = 0`: every copy
its own pose, pose sharing off).

Ours: {gl_line}. Peer: {peer_line}. CPU: {_cpu()}.

Scenario (`scripts/bench_peer.py` docstring): N copies on a square grid spaced 1.5x the model's largest rest
extent, camera above the middle of the near edge at half the grid's width up and 0.6 of it back, looking at
the grid's centre, vertical fov 50 degrees. Each cell: our median frame (ms) and (Panda3D median / ours; the
median over rounds of the same ratio within a round). Above 1x we are faster.

Wall time (median frame):

{chr(10).join(lines)}

CPU time (median frame; every thread of each process, the driver's rasterizer threads included: the work each
engine does, which other jobs on the shared machine inflate far less than the wall time; Panda3D / ours):

{chr(10).join(cpu_lines)}

{chr(10).join('- ' + n for n in notes)}

Machine at the start: {start_note}. At the end: {end_note}.
"""
    write_atomic(args.out, text)


def _cpu() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return f"{line.split(':', 1)[1].strip()}, {os.cpu_count()} logical cores"
    except OSError:
        pass
    return f"{os.cpu_count()} logical cores"


if __name__ == "__main__":
    sys.exit(main())
