"""Benchmark: where the time of full detail (LOD mode "none") goes on heavy skinned characters (issues 21, 29).

The crowds of ``scripts/bench_peer.py`` (its scenario: grid, camera, 1280x720), one DrawList per crowd drawn
by renderer variants on one GL context, round-robin with the order rotated every frame (the machine is
shared; every variant sees the same load). Each variant changes one thing against the shipped renderer:

shipped changes (their image is checked against "before", PSNR in the table)
  before          back faces drawn, headlight from a position varying, 4 influences read per vertex
                  (the renderer before issue 21)
  shipped         back faces of single-sided reps culled, headlight from the pixel's camera ray
                  (render/screen.py: one vertex output fewer), only the influences the mesh uses
                  (SKIN_INFLUENCES_n), 60-byte vertices
  no cull         shipped, but the rep drawn double-sided
  world varying   shipped, but the headlight from the interpolated camera-relative position (v_world)
  4 influences    shipped, but every vertex reads 4 influences
  packed          shipped, but half-float normals, colours and weights (38-byte vertices; not shipped:
                  render/vertex_format.py PACKED_VERTICES)
  no split        shipped, no ``ctx.finish`` between submissions (``max_triangles_in_flight`` None)
diagnostics (not shipped; they change the image: they bound what a part of the pipeline costs)
  flat fragment   the fragment shader writes the vertex colour (no lighting, 4 varyings instead of 10)
  1 influence     the palette loop reads one influence (3 texel fetches instead of 12)
  no fetch        the palette loop reads no texel (the weights still sum constant rows)
  static          the static program (no skinning at all: no joints, weights, palette)
  discard         GL_RASTERIZER_DISCARD: vertex shading only, nothing rasterised
experiments of issue 29 (speeds against "shipped", the per-copy palette path without a pose table; PSNR against it)
  pose sharing    lod.poses at the default rate (the clip's keys): copies in one pose skinned once by the pose
                  cache's compute pass (render/poses/cache.py), every copy drawn from the posed vertices
                  (shaders/poses/posed.vert); the scenario's copies all play from time 0, so they share one pose
  pose sharing, random phases  the same with every copy at a random time of the clip (pose_rate "key")
  exact poses     pose_rate 0: every copy its own pose, each skinned once by the compute pass, drawn from the posed
                  vertices (pose sharing off, the skinning moved out of the vertex stage)
  exact poses, numba  the same with the numba skinning pass instead of the compute shader
  compute raster  the compute rasteriser of small triangles (render/raster/, when this tree has it) with exact poses
                  (pose sharing off)
  both            the compute rasteriser with pose sharing

Reported per variant: the median CPU time of a frame (draw + ``ctx.finish``; every thread of the process, the
driver's rasterizer threads included: the work done, which other jobs on a shared machine do not inflate as
they inflate the wall time), the median wall time, their speeds relative to "shipped" (> 1 faster), and the
shipped variants' PSNR against "before".

Run:  .venv/bin/python scripts/bench_full_detail.py [--models h4 h1 fox] [--counts 100 100 1024]
      [--frames 5] [--variants ...] [--out scripts/bench_full_detail.md]
"""
from __future__ import annotations

import argparse
import dataclasses
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

SHIPPED = ("before", "shipped", "no cull", "world varying", "4 influences", "packed", "no split")
DIAGNOSTIC = ("flat fragment", "1 influence", "no fetch", "static", "discard")
#: notes kept under every run's tables (what was tried and dropped)
NOTES = """
- Tried and dropped (issue 21): triangles in Morton order of their centroids for llvmpipe's vertex splitter
  (`draw_pt_vsplit.c`: segments of 1,024 indices, a 256-entry direct-mapped reuse table). Its cache model says
  the 60 K humanoid's ring-by-ring strips shade each vertex 2.4 times per instance and the Morton order 1.6
  times, but a later run of this script at load 2.4 measured no gain (mesh order vs Morton: 0.99x CPU on h4),
  so the splitter's re-shading is not where this frame's time goes; the change was reverted.
- The pose cache's skinning pass (issue 29): the compute shader (`shaders/poses/pose_skin.comp`) against numba over both
  cores (`render/poses/skin.py`), CPU time of the pass alone at load 14-15: h4 (30,042 vertices, 4 influences) x 100
  poses 75 vs 188 ns per posed vertex, Fox (1,728 vertices) x 1,024 poses 72.5 vs 117 ns (numba includes writing
  the textures); the rows "exact poses" / "exact poses, numba" above compare them inside a frame. The compute
  pass is the default. Its palettes come from a uniform block (1.1x faster than texel fetches, same output).
"""
#: issue 29's experiments: variant -> (pose_rate or None for no pose table, skinning pass, compute raster, random phases)
EXPERIMENTS = {"pose sharing": ("key", "compute", False, False),
               "pose sharing, random phases": ("key", "compute", False, True),
               "exact poses": (0.0, "compute", False, False),
               "exact poses, numba": (0.0, "numba", False, False),
               "compute raster": (0.0, "compute", True, False),
               "both": ("key", "compute", True, False)}
GL_RASTERIZER_DISCARD = 0x8C89

FLAT_FRAGMENT = """#version 330 core
in vec3 v_world;
in vec3 v_normal;
in vec4 v_color;
out vec4 f_color;
void main() { f_color = vec4(v_color.rgb, 1.0); }
"""


def _one_influence(src: str) -> str:
    return src.replace("for (int k = 0; k < SKIN_INFLUENCES; ++k) {", "for (int k = 0; k < 1; ++k) {")


def _no_fetch(src: str) -> str:
    return (src.replace("r0 += w * texelFetch(u_palette, p, 0);", "r0 += w * vec4(1.0, 0.0, 0.0, 1e-9 * float(p.x));")
            .replace("r1 += w * texelFetch(u_palette, p + ivec2(1, 0), 0);", "r1 += w * vec4(0.0, 1.0, 0.0, 0.0);")
            .replace("r2 += w * texelFetch(u_palette, p + ivec2(2, 0), 0);", "r2 += w * vec4(0.0, 0.0, 1.0, 0.0);"))


def make_variant(name, ctx, rep, static_rep, size):
    """(renderer, rep drawn) of variant ``name``."""
    import render.shaders as shaders
    from render.renderer import Renderer

    class Variant(Renderer):
        fragment = None
        patch = None

        def program(self, pname, varyings=(), defines=()):
            defines = tuple(defines) + (("PIXEL_RAY",) if self.pixel_ray and not varyings else ())
            key = (pname, tuple(varyings), tuple(defines))
            if key not in self._programs and not varyings and (self.fragment or self.patch):
                src = shaders.program_sources(pname, fragment=True, defines=tuple(defines))
                if self.fragment:
                    src["fragment_shader"] = self.fragment
                if self.patch:
                    src["vertex_shader"] = self.patch(src["vertex_shader"])
                self._programs[key] = self._track(self.ctx.program(**src), f"variant.{pname}")
                return self._programs[key]
            return super().program(pname, varyings, tuple(d for d in defines if d != "PIXEL_RAY"))

    r = Variant(size, ctx=ctx)
    if hasattr(r, "compute_raster"):  # render/raster/ (issue 29): on only in its experiments
        r.compute_raster = bool(EXPERIMENTS.get(name, (None, None, False))[2])
    if name in EXPERIMENTS:
        r.poses.skinning = EXPERIMENTS[name][1]
    r.packed_vertices = name == "packed"
    drawn = rep
    if name in ("before", "no cull"):
        drawn = dataclasses.replace(rep, double_sided=True)
    if name in ("before", "world varying"):
        r.pixel_ray = False
    if name in ("before", "4 influences"):
        r.specialize_influences = False
    if name == "no split":
        r.max_triangles_in_flight = None
    if name == "flat fragment":
        r.fragment = FLAT_FRAGMENT
    if name == "1 influence":
        r.patch = _one_influence
    if name == "no fetch":
        r.patch = _no_fetch
    if name == "static":
        drawn = static_rep
    r.upload(drawn)
    return r, drawn


def psnr(a, b) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(255.0 ** 2 / mse)


def run_case(path: Path, n: int, variants, frames: int, size):
    import bench_peer as bp

    from crowd.engine import Engine
    from crowd.scene import load_scene
    from lod.full.mode import NoLodSelector
    from lod.full.reps import build_rep
    from sim.gltf.load import load_gltf

    ch = load_gltf(path)
    rest = np.asarray(ch.mesh.positions, np.float64)
    sc = bp.scenario(float((rest.max(0) - rest.min(0)).max()), n)
    with tempfile.TemporaryDirectory() as td:
        sp = Path(td) / "s.toml"
        sp.write_text(bp.scene_text(path.resolve(), ch.clip_names()[0], sc, size))
        eng = Engine(load_scene(sp), quiet=True)
    eng.step()
    cam = eng.camera_at(eng.world.time)
    rep = eng.reps[0]
    static_rep = build_rep(eng.plan.characters[0].mesh, key="static:bench")
    from render.context import create_context

    ctx = create_context()
    cases = {}
    from lod.poses import PoseSharing

    phases = eng.world.state.anim_time.copy()
    for v in variants:
        r, drawn = make_variant(v, ctx, rep, static_rep, size)
        rate, _, _, random_phases = EXPERIMENTS.get(v, (None, None, False, False))
        st = eng.world.state
        if random_phases:  # every copy somewhere in its clip (seeded)
            st.anim_time[:] = np.random.default_rng(1).uniform(0.0, float(rep.clip_duration[0]), st.n)
        dl = NoLodSelector([drawn]).select(st, cam, size)
        st.anim_time[:] = phases
        if rate is not None:
            ps = PoseSharing(rate)
            ps.register([drawn])
            ps.assign(dl)
        cases[v] = (r, dl)
    times = {v: [] for v in variants}
    cpu = {v: [] for v in variants}
    images = {}
    for k in range(frames + 1):  # frame 0 warms up (shader compilation, first uploads)
        rot = k % len(variants)
        for v in variants[rot:] + variants[:rot]:
            r, dl = cases[v]
            if v == "discard":
                ctx.enable_direct(GL_RASTERIZER_DISCARD)
            t0, c0 = time.perf_counter(), time.process_time()
            r.draw(dl)
            t1, c1 = time.perf_counter(), time.process_time()
            if v == "discard":
                ctx.disable_direct(GL_RASTERIZER_DISCARD)
            if k:
                times[v].append(t1 - t0)
                cpu[v].append(c1 - c0)
            if k == frames:
                images[v] = r.read_pixels()
    tris = {v: cases[v][1].triangles for v in variants}
    poses = {v: cases[v][1].stats.get("poses") for v in variants}
    for r, _ in cases.values():
        r.release()
    ctx.release()
    return times, cpu, images, tris, int(ch.mesh.n_triangles), poses


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", nargs="+", default=["h4", "h1", "fox"], choices=["h4", "h1", "fox", "cesiumman"])
    ap.add_argument("--counts", type=int, nargs="+", help="instances per model (default h4/h1/cesiumman 100, fox 1024)")
    ap.add_argument("--frames", type=int, default=5)
    every = list(SHIPPED + DIAGNOSTIC) + list(EXPERIMENTS)
    ap.add_argument("--variants", nargs="+", default=every, choices=every)
    ap.add_argument("--size", type=int, nargs=2, default=[1280, 720])
    ap.add_argument("--models-dir", type=Path, default=ROOT / "out" / "bench_peer" / "models")
    ap.add_argument("--out", type=Path, default=ROOT / "scripts" / "bench_full_detail.md")
    args = ap.parse_args(argv)
    if args.frames < 1:
        print(f"bench_full_detail.py: --frames: expected >= 1, got {args.frames}", file=sys.stderr)
        return 2
    counts = args.counts or [1024 if m == "fox" else 100 for m in args.models]
    if len(counts) != len(args.models):
        print(f"bench_full_detail.py: --counts: expected one count per model ({len(args.models)}), got {len(counts)}",
              file=sys.stderr)
        return 2
    import bench_peer as bp

    paths = bp.model_paths(args.models_dir)
    variants = list(dict.fromkeys(["shipped", *args.variants]))
    from render.renderer import Renderer

    absent = [v for v in variants if EXPERIMENTS.get(v, (0, 0, False))[2] and not hasattr(Renderer, "raster")]
    variants = [v for v in variants if v not in absent]  # the compute rasteriser is not in this tree
    start = bp.machine_note()
    print(f"# start: {start}")
    sections = []
    for mk, n in zip(args.models, counts):
        path, desc = paths[mk]
        if path is None:
            sections.append(f"- {desc}")
            continue
        times, cpu, images, tris, model_tris, poses = run_case(path, n, variants, args.frames, tuple(args.size))
        ref, ref_cpu = statistics.median(times["shipped"]), statistics.median(cpu["shipped"])
        lines = [f"### {desc}, {n:,} copies ({model_tris:,} triangles each)", "",
                 "| variant | CPU ms (median) | speed vs shipped, CPU | wall ms (median) | speed vs shipped, wall | "
                 "triangles submitted | PSNR vs before (dB) |", "| --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
        if absent:
            lines.insert(1, f"(not in this tree, skipped: {', '.join(absent)})")
        print(f"{mk} x{n}")
        for v in variants:
            med, mc = statistics.median(times[v]), statistics.median(cpu[v])
            q = psnr(images[v], images["before"]) if (v in SHIPPED and "before" in images) else None
            if v in EXPERIMENTS and not EXPERIMENTS[v][3]:  # the same times as shipped: PSNR against it
                q = psnr(images[v], images["shipped"])
            qs = "-" if q is None else ("identical" if q == float("inf") else f"{q:.1f}")
            qs += " (vs shipped)" if v in EXPERIMENTS and q is not None else ""
            label = v if poses[v] is None else f"{v} ({poses[v]:,} poses)"
            lines.append(f"| {label} | {mc * 1e3:.1f} | {ref_cpu / mc:.2f}x | {med * 1e3:.1f} | {ref / med:.2f}x | "
                         f"{tris[v]:,} | {qs} |")
            print(f"  {v:14s} cpu {mc * 1e3:8.1f} ms {ref_cpu / mc:.2f}x  wall {med * 1e3:8.1f} ms {ref / med:.2f}x  "
                  f"psnr {qs}")
        sections.append("\n".join(lines))
    end = bp.machine_note()
    print(f"# end: {end}")
    from sim.atomic_io import write_atomic

    text = f"""# Full detail on heavy skinned characters: where the time goes (issues 21, 29)

Command: `scripts/bench_full_detail.py {' '.join(sys.argv[1:] if argv is None else argv)}` ({args.frames} timed frames per
variant after one warm-up, round-robin, order rotated every frame). CPU: {bp._cpu()}. Mesa llvmpipe through EGL.
The scenario of `scripts/bench_peer.py` (grid spaced 1.5x the model's extent, camera above the near edge).
Variants: see the script's docstring; "speed vs shipped" > 1 means faster than the shipped renderer (the per-copy
palette path, no pose table); the PSNR column compares each shipped change's last frame with the renderer before
issue 21 ("before"), and issue 29's experiments (pose sharing, exact poses, compute raster) with "shipped" where
they draw the same times. On a loaded machine the wall times are several times the CPU times: read the CPU
columns (the work of every thread of the process) there.

{chr(10).join(chr(10) + s for s in sections)}

Machine at the start: {start}. At the end: {end}.
{NOTES}"""
    write_atomic(args.out, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
