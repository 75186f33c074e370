"""Frame digests: a fingerprint of what every shipped scene draws in every LOD mode.

For each scene in ``scenes/`` and each LOD mode (``lod.modes.MODES``) the scene
is run headless at a small size for ``--frames`` frames, and the sha256 of the
pixels of frame 0 and of the last frame (and the final simulation-state digest
of ``summary.json``) is written, one line per image:

    <scene> <mode> frame=<n> <sha256 of the RGB(A) pixels>
    <scene> <mode> state <the run's state digest>

A refactor that changes no behaviour leaves this file unchanged: run it before
and after, then ``diff`` (or ``--compare OLD``, which exits 1 on a difference).

Hierarchy builds dominate a cold run (office's characters have up to 110 K
triangles), so the point hierarchies are built with fewer keyframes and one
stratification interval by default (``--lod points:keyframes=3
--lod points:intervals=1``, as ``bench_auto.py`` does); every algorithm still
runs. Mode auto keeps its stored cost model (``--lod auto:adapt=false``): rescaled
to measured frame times it would choose by the machine's load. Hierarchies come
from ``$CROWD_CACHE_DIR`` (warm after the first run).

Run:  .venv/bin/python scripts/frame_digests.py [--out scripts/frame_digests.txt] [--scenes grid office]
      [--modes none points] [--frames 4] [--size 160 90] [--lod MODE:KEY=VALUE ...] [--compare OLD.txt]
"""
from __future__ import annotations

import argparse
import hashlib
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

DEFAULT_LOD = ("points:keyframes=3", "points:intervals=1", "auto:keyframes=3", "auto:adapt=false")
#: scenes digested only when --scenes names them (scripts/bench_million.py measures the million agents)
NAMED_ONLY = ("million",)


def _value(text: str):
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def pixel_digest(path: Path) -> str:
    from PIL import Image

    with Image.open(path) as im:
        h = hashlib.sha256(f"{im.mode}{im.size}".encode())
        h.update(im.tobytes())
    return h.hexdigest()


def run_one(scene_path: Path, mode: str, frames: int, size: tuple, lod: dict) -> list:
    """Lines of one scene in one mode."""
    from crowd.engine import Engine
    from crowd.report.settings import expand_settings

    sweeps = [("lod.mode", [mode])] + [(f"lod.{k}", [v]) for k, v in lod.get(mode, {}).items()]
    setting = expand_settings(scene_path, sweeps, size=size, frames=frames)[0]
    lines = []
    with tempfile.TemporaryDirectory(prefix="frame-digest-") as d:
        out = Path(d) / "run"
        with Engine(setting.scene, quiet=True) as engine:
            r = engine.run(frames=frames, out_dir=out, png_every=frames - 1)
        for p in sorted(Path(x) for x in r.pngs):
            n = int(p.stem.split("_")[-1])
            lines.append(f"{scene_path.stem} {mode} frame={n} {pixel_digest(p)}")
        lines.append(f"{scene_path.stem} {mode} state {r.summary.get('state_digest', '?')}")
    return lines


def main(argv=None) -> int:
    from lod.modes import mode_names

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "scripts" / "frame_digests.txt"))
    ap.add_argument("--scenes", nargs="*", default=None,
                    help="scene names (default: every scenes/*.toml but " + ", ".join(NAMED_ONLY) + ")")
    ap.add_argument("--modes", nargs="*", default=None, help="LOD modes (default: all)")
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--size", type=int, nargs=2, default=(160, 90))
    ap.add_argument("--lod", action="append", default=None, help="MODE:KEY=VALUE, a [lod] key for one mode")
    ap.add_argument("--compare", default=None, help="an earlier digest file: exit 1 when any line differs")
    a = ap.parse_args(argv)
    if a.frames < 2:
        ap.error("--frames must be at least 2 (frame 0 and a later one)")
    lod: dict = {}
    for item in (a.lod if a.lod is not None else DEFAULT_LOD):
        try:
            mode, kv = item.split(":", 1)
            k, v = kv.split("=", 1)
        except ValueError:
            ap.error(f"--lod {item!r}: expected MODE:KEY=VALUE")
        lod.setdefault(mode, {})[k] = _value(v)
    scenes = sorted((ROOT / "scenes").glob("*.toml"))
    if a.scenes:
        unknown = sorted(set(a.scenes) - {s.stem for s in scenes})
        if unknown:
            ap.error(f"--scenes: no scenes/{unknown[0]}.toml; accepted: {', '.join(s.stem for s in scenes)}")
        scenes = [s for s in scenes if s.stem in a.scenes]
    else:  # a million agents in every mode (mode none: 5 G triangles a frame) only when named
        scenes = [s for s in scenes if s.stem not in NAMED_ONLY]
    modes = a.modes or list(mode_names())
    for m in set(modes) | set(lod):
        if m not in mode_names():
            ap.error(f"unknown LOD mode {m!r}; accepted: {', '.join(mode_names())}")
    old = None
    if a.compare:
        try:
            old = Path(a.compare).read_text(encoding="utf-8").splitlines()
        except OSError as e:
            ap.error(f"--compare {a.compare}: cannot read it ({e.strerror})")
    from crowd.report.runs import _user_errors
    from lod.atomic_io import write_atomic

    lines = []
    for s in scenes:
        for m in modes:
            t0 = time.perf_counter()
            try:
                got = run_one(s, m, a.frames, tuple(a.size), lod)
            except _user_errors() as e:  # e.g. a --lod key the mode does not accept: one sentence, exit 2
                print(f"frame_digests: {s.name} in mode {m}: {str(e).splitlines()[0]}", file=sys.stderr)
                return 2
            lines += got
            print(f"{s.stem:12s} {m:10s} {time.perf_counter() - t0:7.1f} s  " + " ".join(x.split()[-1][:12] for x in got),
                  flush=True)
    out = Path(a.out)
    write_atomic(out, "\n".join(lines) + "\n")
    print(f"{len(lines)} lines -> {out}")
    if old is not None:
        diff = sorted(set(old) ^ set(lines))
        for line in diff:
            print(("- " if line in old else "+ ") + line)
        print("digests equal" if not diff else f"{len(diff)} lines differ")
        return 1 if diff else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
