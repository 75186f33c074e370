"""Frame digests: a fingerprint of what every shipped scene draws in every LOD mode.

For each scene in ``scenes/`` and each LOD mode (``lod.modes.MODES``) the scene
is run headless at a small size for ``--frames`` frames, and the sha256 of the
pixels of frame 0 and of the last frame (and the final simulation-state digest
of ``summary.json``) is written, one line per image:

    <scene> <mode> frame=<n> <sha256 of the RGB(A) pixels>
    <scene> <mode> state <the run's state digest>

Beside each run it prints how many poses a frame evaluated beyond its distinct poses (frames.csv
``pose_passes`` minus ``poses``): 0 when the pose cache is the one place animation is evaluated (issue 33).

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
      [--keep DIR [--psnr OLD_DIR]]

A change that may move pixels (issue 44's pose evaluation) keeps the images of both runs (``--keep``) and prints
every changed image's PSNR against the old one (``--psnr OLD_DIR``).
"""
from __future__ import annotations

import argparse
import hashlib
import shutil
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


def pose_excess(frames_csv: Path) -> int:
    """The most poses any frame of a run evaluated beyond its distinct poses (frames.csv ``pose_passes`` minus
    ``poses``; issue 33: 0 on every frame when each distinct pose is evaluated once)."""
    import csv

    worst = 0
    with open(frames_csv, newline="", encoding="utf-8") as f:
        for row in csv.DictReader(f):
            passes = float(row.get("pose_passes") or 0.0)
            worst = max(worst, int(round(passes - float(row.get("poses") or 0.0))))
    return worst


def psnr(a_path: Path, b_path: Path) -> float:
    """PSNR in dB of two images of one size (RGB, peak 255); inf when equal."""
    import numpy as np
    from PIL import Image

    a = np.asarray(Image.open(a_path).convert("RGB"), np.float64)
    b = np.asarray(Image.open(b_path).convert("RGB"), np.float64)
    mse = float(np.mean((a - b) ** 2))
    return float("inf") if mse == 0.0 else 10.0 * np.log10(255.0 ** 2 / mse)


def run_one(scene_path: Path, mode: str, frames: int, size: tuple, lod: dict, excess: dict | None = None,
            keep: Path | None = None) -> list:
    """Lines of one scene in one mode (``excess``: filled with (scene, mode) -> :func:`pose_excess`; ``keep``: a
    folder the images are copied to as ``<scene>_<mode>_frame<n>.png``)."""
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
            if keep is not None:
                shutil.copyfile(p, keep / f"{scene_path.stem}_{mode}_frame{n}.png")
        lines.append(f"{scene_path.stem} {mode} state {r.summary.get('state_digest', '?')}")
        if excess is not None and (out / "frames.csv").exists():
            excess[(scene_path.stem, mode)] = pose_excess(out / "frames.csv")
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
    ap.add_argument("--keep", default=None, help="a folder to keep the images in (<scene>_<mode>_frame<n>.png)")
    ap.add_argument("--psnr", default=None, help="with --keep: an earlier run's --keep folder; every image that "
                    "differs is printed with its PSNR against the earlier one")
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
    from crowd.scene import shipped_scenes

    scenes = shipped_scenes(ROOT / "scenes")  # those whose data are here
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
    keep = Path(a.keep) if a.keep else None
    if keep is not None:
        try:
            keep.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            ap.error(f"--keep {a.keep}: cannot make that folder ({e.strerror})")
    if a.psnr and keep is None:
        ap.error("--psnr needs --keep (the images to compare)")
    old = None
    if a.compare:
        try:
            old = Path(a.compare).read_text(encoding="utf-8").splitlines()
        except OSError as e:
            ap.error(f"--compare {a.compare}: cannot read it ({e.strerror})")
    from crowd.errors import user_errors
    from sim.atomic_io import write_atomic

    lines = []
    excess: dict = {}
    for s in scenes:
        for m in modes:
            t0 = time.perf_counter()
            try:
                got = run_one(s, m, a.frames, tuple(a.size), lod, excess, keep)
            except user_errors() as e:  # e.g. a --lod key the mode does not accept: one sentence, exit 2
                print(f"frame_digests: {s.name} in mode {m}: {str(e).splitlines()[0]}", file=sys.stderr)
                return 2
            lines += got
            print(f"{s.stem:12s} {m:10s} {time.perf_counter() - t0:7.1f} s  " + " ".join(x.split()[-1][:12] for x in got)
                  + f"  pose passes beyond distinct poses: {excess.get((s.stem, m), '?')}", flush=True)
    out = Path(a.out)
    write_atomic(out, "\n".join(lines) + "\n")
    print(f"{len(lines)} lines -> {out}")
    over = {k: v for k, v in excess.items() if v > 0}
    print("pose passes: at most one per distinct pose on every frame" if not over else
          "pose passes beyond the distinct poses: " + ", ".join(f"{sc} {mo} +{v}" for (sc, mo), v in sorted(over.items())))
    if old is not None:
        diff = sorted(set(old) ^ set(lines))
        for line in diff:
            print(("- " if line in old else "+ ") + line)
        print("digests equal" if not diff else f"{len(diff)} lines differ")
    if a.psnr:
        worst = float("inf")
        for p in sorted(keep.glob("*.png")):
            q = Path(a.psnr) / p.name
            if not q.is_file():
                print(f"psnr: {p.name}: not in {a.psnr}")
                continue
            v = psnr(p, q)
            worst = min(worst, v)
            if v != float("inf"):
                print(f"psnr: {p.stem} {v:.1f} dB")
        print(f"psnr: lowest {worst:.1f} dB over the images that differ" if worst < float("inf") else
              "psnr: every image equal")
    if old is not None:
        return 1 if diff else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
