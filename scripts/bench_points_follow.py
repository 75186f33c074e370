"""Benchmark: mode points with samples that follow the animation against the per-keyframe-pair octrees, same
crowds, same views, same run (issue 27's draw-speed acceptance: within 1.15x of today's points frame or faster,
image error no worse by more than 1 dB).

Crowds (the ones points already serves):

- ``grid``: ``scenes/grid.toml`` (90,000 agents of four 6,396-triangle humanoids, hierarchical instancing §3.6),
  from its camera's first view;
- ``fox``: ``../shared/assets/Fox.glb`` x1,024 in ``scripts/bench_peer.py``'s scenario (a square grid spaced
  1.5 extents, camera above the near edge; skipped when the assets are absent);
- ``h4``, ``h1``: the generated 60 K-triangle humanoids of ``scripts/peer_models.py`` (four influences; one
  influence in 59 primitives) x100 in the same scenario;
- ``horse`` (not by default): ``Horse.glb`` x1,024, a keyframed flip-book, the measurement behind the rule that
  keeps short flip-books baked (``lod.points.paths``).

For each crowd one engine simulates; mode points is built twice from the same characters, instancing groups and
played clips: ``animation = "baked"`` (today's path, Wand & Straßer §3.3) and ``"follow"`` (``lod.points.follow``);
each frame the world steps once and both selectors select and draw it, in an order alternating every frame (a
frame: select + draw + ``ctx.finish``). Reported: the median frame of each, their ratio (follow / baked, the
median of the per-frame ratios: load cancels in it), the points and triangles drawn, the samples placed and
poses, and the PSNR of the last frame of each against the true reference (full detail, 4 x 4 samples per pixel,
box-filtered; crowd.reference) at the same state.

Run:  .venv/bin/python scripts/bench_points_follow.py [--crowds grid fox h4 h1 horse] [--frames 7] [--warmup 2]
      [--size 1280 720] [--skip-none] [--out scripts/bench_points_follow.md]
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
for p in (ROOT, ROOT / "scripts"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

CROWDS = ("grid", "fox", "h4", "h1", "horse")
#: the crowds of the acceptance (``horse``, a keyframed flip-book, measures the rule that bakes short flip-books)
DEFAULT_CROWDS = ("grid", "fox", "h4", "h1")
ASSETS = Path(os.environ.get("CROWD_SHARED_ASSETS", ROOT.parent / "shared" / "assets"))


def _scene(crowd: str, size, td: Path):
    """(scene path, description) of a crowd, or (None, why skipped)."""
    if crowd == "grid":
        return ROOT / "scenes" / "grid.toml", "grid: 90,000 agents, 4 x 6,396 triangles, instancing (scenes/grid.toml)"
    from bench_peer import scenario, scene_text

    from sim.gltf.load import load_gltf

    if crowd in ("fox", "horse"):
        path = ASSETS / ("Fox.glb" if crowd == "fox" else "Horse.glb")
        if not path.is_file():
            return None, f"{crowd}: {path} absent, skipped"
        n, desc = 1024, ("Fox.glb x1,024 (576 triangles; bench_peer scenario)" if crowd == "fox" else
                         "Horse.glb x1,024 (984 triangles, morph flip-book: keyframed; bench_peer scenario)")
    else:
        from peer_models import write_models

        gen = write_models(td / "models")
        path = gen["humanoid60k-4inf" if crowd == "h4" else "humanoid60k-1inf-59prims"]
        n, desc = 100, ("60 K humanoid x100, 4 influences" if crowd == "h4" else
                        "60 K humanoid x100, 1 influence, 59 primitives") + " (peer_models; bench_peer scenario)"
    ch = load_gltf(path)
    rest = np.asarray(ch.mesh.positions, np.float64)
    sc = scenario(float((rest.max(0) - rest.min(0)).max()), n)
    scene = td / f"{crowd}.toml"
    scene.write_text(scene_text(path.resolve(), ch.clip_names()[0] if ch.clip_names() else "", sc, size))
    return scene, desc


def _variants(eng):
    """[(label, reps, selector)]: mode points on the per-keyframe-pair path and on the follow path."""
    from lod.points import mode as pm

    sc = eng.scene
    chars = eng.plan.characters
    names = [c.name for c in sc.characters]
    fps = [c.fps for c in sc.characters]
    params = dict(sc.lod_params)
    params.pop("animation", None)
    extra = {"instancing": eng.world.resources.get("instancing"), "clips": eng._played_clips()}
    out = []
    for label in ("baked", "follow"):
        reps, sel = pm.build(chars, [f"{n}~{label}" for n in names], fps, {**params, "animation": label},
                             static_reps=eng.statics, progress=False, **extra)
        out.append((label, reps, sel))
    return out


def run_crowd(crowd: str, args, td: Path) -> dict | None:
    from crowd.engine import Engine
    from crowd.image_metrics import psnr
    from crowd.scene import load_scene

    scene_path, desc = _scene(crowd, tuple(args.size), td)
    if scene_path is None:
        print(f"# {desc}")
        return {"crowd": crowd, "desc": desc, "skipped": True}
    import dataclasses

    # the engine simulates and holds mode none (the reference image); both point paths are built below
    scene = dataclasses.replace(load_scene(scene_path), lod_mode="none", lod_params=())
    t0 = time.perf_counter()
    eng = Engine(scene, quiet=True)
    try:
        variants = _variants(eng)
        build_s = time.perf_counter() - t0
        r = eng.open_renderer()
        for _, reps, _ in variants:
            for rep in reps:
                r.upload(rep)
        bg = eng.scene.render.background
        size = r.size
        times = {v[0]: [] for v in variants}
        ratio, stats = [], {}
        imgs = {}
        for k in range(args.warmup + args.frames):
            eng.step()
            cam = eng.camera_at(0.0)
            order = variants if k % 2 == 0 else variants[::-1]
            got = {}
            for label, _, sel in order:
                a = time.perf_counter()
                dl = sel.select(eng.world.state, cam, size)
                r.draw(dl, bg)
                r.ctx.finish()
                got[label] = time.perf_counter() - a
                stats[label] = dict(dl.stats)
                if k == args.warmup + args.frames - 1:
                    imgs[label] = r.read_pixels()
            if k >= args.warmup:
                for label, s in got.items():
                    times[label].append(s)
                ratio.append(got["follow"] / got["baked"])
        ps = {}
        if not args.skip_none:  # the true reference: full detail, 4 x 4 samples per pixel (crowd.reference)
            from crowd.reference import DEFAULT_K, TileRenderer

            with TileRenderer(size, DEFAULT_K, ctx=r.ctx, reps=eng.reps) as tiles:
                eng._lit(tiles.renderer)
                ref = tiles.draw(eng.selector.select(eng.world.state, eng.camera_at(0.0), tiles.big), bg)
            ps = {label: psnr(img, ref) for label, img in imgs.items()}
    finally:
        eng.close()
    row = {"crowd": crowd, "desc": desc, "build_s": build_s, "size": size,
           "ms": {k: 1e3 * statistics.median(v) for k, v in times.items()}, "ratio": statistics.median(ratio),
           "psnr": ps, "stats": stats}
    s = row["stats"]
    print(f"{crowd}: baked {row['ms']['baked']:.1f} ms, follow {row['ms']['follow']:.1f} ms, follow/baked "
          f"{row['ratio']:.2f}; points {s['baked'].get('points')} / {s['follow'].get('points')}, triangles "
          f"{s['baked'].get('triangles')} / {s['follow'].get('triangles')}, placed {s['follow'].get('placed_points', 0)}"
          f" in {s['follow'].get('point_poses', 0)} poses; PSNR vs reference "
          + (", ".join(f"{k} {v:.2f} dB" for k, v in ps.items()) or "skipped") + f"; load {os.getloadavg()[0]:.1f}",
          flush=True)
    return row


def write_md(args, rows, start: str, end: str) -> None:
    from sim.atomic_io import write_atomic

    cmd = "scripts/bench_points_follow.py " + " ".join(sys.argv[1:])
    lines = ["| crowd | baked ms | follow ms | follow / baked (median of per-frame ratios) | points baked / follow "
             "| triangles baked / follow | samples placed (poses) | PSNR vs reference baked / follow dB |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    notes = []
    for r in rows:
        if r.get("skipped"):
            notes.append(r["desc"])
            continue
        s = r["stats"]
        p = r["psnr"]
        lines.append(f"| {r['desc']} | {r['ms']['baked']:.1f} | {r['ms']['follow']:.1f} | {r['ratio']:.2f} | "
                     f"{s['baked'].get('points', 0):,} / {s['follow'].get('points', 0):,} | "
                     f"{s['baked'].get('triangles', 0):,} / {s['follow'].get('triangles', 0):,} | "
                     f"{s['follow'].get('placed_points', 0):,} ({s['follow'].get('point_poses', 0)}) | "
                     + (f"{p['baked']:.2f} / {p['follow']:.2f}" if p else "-") + " |")
    text = f"""# bench_points_follow: samples that follow the animation vs the per-keyframe-pair octrees (issue 27)

Command: `{cmd}` ({args.frames} timed frames after {args.warmup} warm-up frames, each frame both paths,
alternating order; {args.size[0]}x{args.size[1]}; Mesa llvmpipe). Target: follow within 1.15x of baked or
faster, PSNR against the reference no worse by more than 1 dB.

{chr(10).join(lines)}

{chr(10).join('- ' + n for n in notes)}

Machine at the start: {start}. At the end: {end}.
"""
    write_atomic(args.out, text)


def main(argv=None) -> int:
    from bench_peer import machine_note

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--crowds", nargs="+", default=list(DEFAULT_CROWDS), choices=list(CROWDS))
    ap.add_argument("--frames", type=int, default=7)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--size", type=int, nargs=2, default=[1280, 720])
    ap.add_argument("--skip-none", action="store_true", help="no PSNR against the reference (its grid frame is slow)")
    ap.add_argument("--out", type=Path, default=ROOT / "scripts" / "bench_points_follow.md")
    args = ap.parse_args(argv)
    if args.frames < 1 or args.warmup < 0 or min(args.size) < 16:
        print("bench_points_follow.py: --frames >= 1, --warmup >= 0 and --size >= 16 x 16 expected", file=sys.stderr)
        return 2
    start = machine_note()
    print(f"# start: {start}")
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-points-follow-") as td:
        for c in args.crowds:
            rows.append(run_crowd(c, args, Path(td)))
    end = machine_note()
    print(f"# end: {end}")
    write_md(args, rows, start, end)
    return 0


if __name__ == "__main__":
    sys.exit(main())
