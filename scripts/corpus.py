"""Corpus check: every glTF character under some folders through info, build and a frame in every LOD mode.

For each ``.glb`` / ``.gltf`` file under the folders given (recursively; with
``--with-generated`` also the generated corpus of ``scripts/corpus_models.py``), in a
subprocess of its own (so a crash or a hang is caught, not inherited):

1. ``info``: the character is loaded as ``crowd info`` loads it;
2. build: every LOD mode's representations are built (``lod.modes``), timed;
3. a frame: a 3x3 grid of copies (spaced 1.5x the model's largest rest extent,
   camera above the middle of one edge looking at the centre) rendered at a
   small size in every mode through the engine ``crowd run`` uses;
4. the frame of each mode, mode ``none`` included, is compared with the true reference of the same frame (full
   detail with 4 x 4 samples per pixel, box-filtered: ``crowd.reference``; PSNR, SSIM).

One table row per model and mode: ``ok``, ``refused`` (the one-line message a
user would get: bad input, exit 2) or ``FAILED`` (a traceback, a crash, a NaN
in the image, a hang past ``--timeout``), build seconds, poses baked per clip
(mode points), triangles and points drawn, PSNR and SSIM against the true reference.
The table is printed and, with ``--md FILE``, written there (atomically).
Exits 1 when any row is FAILED.

Run:  .venv/bin/python scripts/corpus.py DIR... [--with-generated] [--md docs/corpus.md] [--size 240 160] [--timeout 900]
      [--modes none triangles clusters points auto] [--frames DIR]       (make corpus: ../shared/assets)
"""
from __future__ import annotations

import argparse
import json
import math
import re
import os
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

MODES = ("none", "triangles", "clusters", "points", "auto")


def _scene_text(model: Path, ext: float, center, size: tuple, mode: str, clip: str) -> str:
    """A scene of a 3x3 grid of ``model`` (spacing 1.5 extents), one frame, camera over one edge."""
    sp = 1.5 * ext
    width = 3 * sp
    cx, cy, cz = center
    origin = [cx - sp, 0.0, cz - sp]
    cam = [cx, cy + 0.5 * width, cz + 0.6 * width + sp]
    clip_line = f'clip = "{clip}"\n' if clip else ""
    return f'''name = "corpus"
seed = 1
dt = 0.0333333
frames = 1
effects = ["animation"]

[[characters]]
name = "model"
file = {json.dumps(str(model))}

[[placement]]
kind = "grid"
character = "model"
{clip_line}rows = 3
cols = 3
spacing = [{sp!r}, {sp!r}]
origin = [{origin[0]!r}, {origin[1]!r}, {origin[2]!r}]
heading = 0.0
phase = "zero"

[camera]
fov = 50.0
near = {max(1e-3, 0.01 * ext)!r}
far = {20.0 * width + 10.0 * ext!r}
keys = [{{ time = 0.0, position = [{cam[0]!r}, {cam[1]!r}, {cam[2]!r}], target = [{cx!r}, {cy!r}, {cz!r}] }}]

[render]
size = [{size[0]}, {size[1]}]
png_every = 1

[lod]
mode = "{mode}"
'''


def check_model(model: Path, size: tuple, modes: tuple, keep: str | None = None) -> dict:
    """Rows of one model (run in a subprocess by :func:`main`)."""
    import numpy as np

    from crowd.characters import build_character, parse_asset
    from crowd.engine import Engine
    from crowd.errors import user_errors
    from crowd.image_metrics import psnr, ssim
    from crowd.scene import load_scene
    from lod.modes import mode_module
    from crowd.images import read_png
    from sim.describe import describe

    rows = []
    try:
        spec = parse_asset(str(model))
        ch = build_character(spec)
        describe(ch)
    except user_errors() as e:
        return {"model": model.name, "rows": [{"mode": m, "status": "refused", "note": _line(e)} for m in modes]}
    if hasattr(ch, "mesh"):
        p = np.asarray(ch.mesh.positions, np.float64)
    else:  # keyframed: the first pose of the first animation
        p = np.asarray(next(iter(ch.animations.values())).keyframes[0].positions, np.float64)
    lo, hi = p.min(axis=0), p.max(axis=0)
    ext = float(np.max(hi - lo)) if p.size and np.isfinite(hi - lo).all() else 1.0
    ext = ext if ext > 0 else 1.0
    center = [0.0, 0.5 * float(lo[1] + hi[1]) if p.size else 0.0, 0.0]  # the grid's centre, mid-height
    clip = ""
    images = {}
    with tempfile.TemporaryDirectory(prefix="corpus-") as d:
        d = Path(d)
        for mode in modes:
            row = {"mode": mode, "status": "ok", "note": ""}
            rows.append(row)
            try:
                t0 = time.perf_counter()
                module = mode_module(mode)
                reps, _ = module.build([ch], ["model"], [30], {}, progress=False)
                row["build_s"] = time.perf_counter() - t0
                poses = [getattr(r, "poses", None) for r in reps]
                poses = next((x for x in poses if x), None)
                if poses:
                    row["poses"] = ", ".join(f"{n} {len(cp.times)}" for n, cp in poses.items())
                elif any(getattr(r, "follow", False) for r in reps):  # lod.points.follow: one hierarchy, no poses
                    row["poses"] = "follow"
                scene_path = d / f"{mode}.toml"
                scene_path.write_text(_scene_text(model, ext, center, size, mode, clip))
                scene = load_scene(scene_path).with_overrides(out=d / f"out-{mode}")
                with Engine(scene, quiet=True) as engine:
                    r = engine.run()
                counts = r.summary["counts"]
                row["triangles"] = int(counts["triangles"]["mean"])
                row["points"] = int(counts.get("points", {}).get("mean", 0))
                png = sorted(Path(x) for x in r.pngs)[0]
                img = read_png(png)
                if not np.isfinite(np.asarray(img, np.float64)).all():
                    raise FloatingPointError("NaN in the image")
                images[mode] = img
                if mode == "none":  # the true reference of the same frame (crowd.reference)
                    from crowd.reference import DEFAULT_K, reference_frames

                    frame = int(re.search(r"(\d+)", png.name).group(1))
                    images["reference"] = reference_frames(scene, [frame], DEFAULT_K)["images"][frame]
                if keep:
                    import shutil

                    Path(keep).mkdir(parents=True, exist_ok=True)
                    shutil.copyfile(png, Path(keep) / f"{model.stem}-{mode}.png")
            except user_errors() as e:
                row["status"], row["note"] = "refused", _line(e)
            except Exception as e:  # noqa: BLE001 - the corpus reports every failure as a row
                row["status"] = "FAILED"
                row["note"] = f"{type(e).__name__}: {_line(e)}"
                row["traceback"] = traceback.format_exc(limit=-3)
    ref = images.get("reference")
    for row in rows:
        img = images.get(row["mode"])
        if ref is not None and img is not None:
            v = psnr(img, ref)
            row["psnr"] = v if math.isfinite(v) else None
            row["ssim"] = ssim(img, ref)
    return {"model": model.name, "rows": rows}


def _line(e) -> str:
    s = str(e).strip().splitlines()
    return s[0] if s else type(e).__name__


def _fmt(v, f) -> str:
    return "" if v is None else (f.format(v) if not isinstance(v, str) else v)


def table(results: list) -> str:
    head = ("| model | mode | result | build s | poses per clip | triangles | points | PSNR dB vs reference | SSIM | "
            "note |\n"
            "| --- | --- | --- | ---: | --- | ---: | ---: | ---: | ---: | --- |")
    lines = [head]
    for res in results:
        for r in res["rows"]:
            psnr = r.get("psnr", None)
            lines.append("| " + " | ".join([
                res["model"], r["mode"], r["status"], _fmt(r.get("build_s"), "{:.1f}"), r.get("poses", ""),
                _fmt(r.get("triangles"), "{:,}"), _fmt(r.get("points"), "{:,}"),
                "identical" if ("psnr" in r and psnr is None) else _fmt(psnr, "{:.1f}"),
                _fmt(r.get("ssim"), "{:.3f}"), r.get("note", "").replace("|", "/")]) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="*", help="folders searched recursively for .glb/.gltf")
    ap.add_argument("--md", default=None, help="write the table (with the command and machine) to this file")
    ap.add_argument("--size", type=int, nargs=2, default=(240, 160))
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per model before it counts as a hang")
    ap.add_argument("--modes", nargs="*", default=list(MODES))
    ap.add_argument("--frames", default=None, help="keep each model's frame per mode here (MODEL-MODE.png)")
    ap.add_argument("--with-generated", action="store_true",
                    help="also the generated corpus (scripts/corpus_models.py), written to a temporary folder")
    ap.add_argument("--one", default=None, help=argparse.SUPPRESS)  # internal: check one model, print JSON
    a = ap.parse_args(argv)
    bad = [m for m in a.modes if m not in MODES]
    if bad:
        ap.error(f"--modes: unknown {', '.join(bad)}; accepted: {', '.join(MODES)}")
    if a.one:
        print("CORPUS-JSON " + json.dumps(check_model(Path(a.one), tuple(a.size), tuple(a.modes), a.frames)))
        return 0
    files = []
    gen = None
    if a.with_generated:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from corpus_models import write_models

        gen = tempfile.TemporaryDirectory(prefix="corpus-models-")
        files += write_models(gen.name)
    for d in a.dirs:
        p = Path(d)
        if not p.is_dir():
            print(f"{d}: not a folder; expected folders holding .glb/.gltf files", file=sys.stderr)
            return 2
        files += sorted(x for x in p.rglob("*") if x.suffix.lower() in (".glb", ".gltf") and x.is_file())
    if not files:
        print("no .glb/.gltf files under " + (", ".join(a.dirs) or "no folder"), file=sys.stderr)
        return 2
    results = []
    for f in files:
        t0 = time.perf_counter()
        cmd = [sys.executable, str(Path(__file__).resolve()), "--one", str(f.resolve()), "--size", *map(str, a.size),
               "--modes", *a.modes] + (["--frames", str(Path(a.frames).resolve())] if a.frames else [])
        env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
        try:
            pr = subprocess.run(cmd, capture_output=True, text=True, timeout=a.timeout, env=env, cwd=ROOT)
            line = next((x for x in pr.stdout.splitlines() if x.startswith("CORPUS-JSON ")), None)
            if line is None:
                tail = (pr.stderr.strip().splitlines() or [f"exit code {pr.returncode}"])[-1]
                res = {"model": f.name, "rows": [{"mode": "*", "status": "FAILED",
                                                  "note": f"crashed (exit {pr.returncode}): {tail}"}]}
            else:
                res = json.loads(line[len("CORPUS-JSON "):])
        except subprocess.TimeoutExpired:
            res = {"model": f.name, "rows": [{"mode": "*", "status": "FAILED", "note": f"hang: over {a.timeout:g} s"}]}
        results.append(res)
        status = ", ".join(f"{r['mode']} {r['status']}" for r in res["rows"])
        print(f"{f.name}: {status} ({time.perf_counter() - t0:.0f} s)", flush=True)
        for r in res["rows"]:
            if r.get("traceback"):
                print(r["traceback"], file=sys.stderr)
    text = table(results)
    print(text)
    failed = sum(r["status"] == "FAILED" for res in results for r in res["rows"])
    if a.md:
        import platform

        from sim.atomic_io import write_atomic

        cmdline = "scripts/corpus.py " + " ".join(a.dirs + (["--with-generated"] if a.with_generated else []))
        write_atomic(a.md, f"# Corpus\n\nGenerated by `{cmdline}` on {time.strftime('%Y-%m-%d')} "
                           f"({platform.processor() or platform.machine()}, {os.cpu_count()} cores; frames at "
                           f"{a.size[0]}x{a.size[1]}, a 3x3 grid of copies). {failed} FAILED.\n\n{text}\n")
    if gen is not None:
        gen.cleanup()
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
