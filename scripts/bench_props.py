"""Cost of the world around the crowd: prop chains, their LOD, and drawing ground, solids and props.

Three figures, measured in one run:

1. Chain build (no cache) of every shipped prop (``scenes/props/``): seconds, triangles and
   measured error (mm) per level (``lod.props.chain``).
2. Props LOD along ``scenes/quickstart.toml``'s camera path: prop triangles per frame in mode ``none``
   (full detail) against the pixels-of-error rule (``[lod] poe`` 1 and 3), selection only.
3. Drawing the world alone at ``--size`` (default 1280x720) from exhibition's and office's cameras:
   the minimum and median over ``--repeat`` frames of an empty frame, the ground, the props and
   obstacle solids, and all of it (upload + draw + finish, seconds of ``Renderer.draw``); the
   differences to the empty frame are the world's cost. Frames of each kind are interleaved, so
   machine load drifts onto all of them alike; the CPU time of the process (all threads, llvmpipe's
   included) per frame is printed too: on a shared machine it is the figure the load inflates least
   (the wall time of an unloaded 2-core machine is about half of it: llvmpipe renders on both cores).

Usage::

    python scripts/bench_props.py [--size WxH] [--repeat N]
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def chains() -> list:
    from lod.props.chain import build_chain
    from sim.props import load_prop_mesh

    lines = []
    for f, up in (("stand.glb", "y"), ("desk.obj", "y"), ("planter.ply", "y"), ("lamp.stl", "z")):
        mesh = load_prop_mesh(ROOT / "scenes" / "props" / f, up)
        t = time.perf_counter()
        rep = build_chain(mesh, f)
        dt = time.perf_counter() - t
        levels = ", ".join(f"{int(c)} ({e * 1e3:.1f})" for c, e in zip(rep.level_count, rep.level_error))
        lines.append(f"  {f}: {dt:.2f} s; levels: triangles (error mm): {levels}")
    return lines


def props_lod() -> list:
    from crowd.engine import Engine
    from crowd.scene import load_scene

    sc = load_scene(ROOT / "scenes" / "quickstart.toml")
    out = []
    with Engine(sc, quiet=True) as e:
        sel = e.scenery.selector
        times = np.linspace(0.0, sc.frames * sc.dt, 40)
        for label, kw in (("none (full detail)", {"full_detail": True}), ("poe 1", {"poe": 1.0}),
                          ("poe 3", {"poe": 3.0})):
            tris = [sel.select(e.camera_at(float(t)), sc.render.size, **kw)[1]["props"] for t in times]
            out.append(f"  {label}: {np.mean(tris):,.0f} prop triangles per frame (min {min(tris):,}, "
                       f"max {max(tris):,})")
    return out


def _cpu() -> float:
    """CPU seconds of this process, all threads (llvmpipe's too): a cost other jobs' load does not inflate."""
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def world_draw(size, repeat: int) -> list:
    from crowd.engine import Engine
    from crowd.scene import load_scene
    from lod.drawlist import DrawList

    out = []
    for name in ("exhibition", "office"):
        sc = load_scene(ROOT / "scenes" / f"{name}.toml").with_overrides(size=size)
        with Engine(sc, quiet=True) as e:
            r = e.open_renderer()
            cam = e.camera_at(2.0)
            t = time.perf_counter()
            batches, stats = e.scenery.selector.select(cam, size, poe=1.0)
            sel_ms = (time.perf_counter() - t) * 1e3
            kinds = {"empty": [], "ground": [b for b in batches if b.rep == "world:ground"],
                     "props+solids": [b for b in batches if b.rep != "world:ground"], "all": batches}
            dls = {k: DrawList(origin=cam.position, view=cam.view_matrix().astype(np.float32),
                               proj=cam.projection(size[0] / size[1]).astype(np.float32), size=size, batches=bs)
                   for k, bs in kinds.items()}
            ms = {k: [] for k in kinds}
            cpu = {k: 0.0 for k in kinds}
            for i in range(repeat + 2):
                for k, dl in dls.items():
                    c0 = _cpu()
                    t = r.draw(dl, sc.render.background)
                    if i >= 2:  # warm-up frames compile shaders and grow buffers
                        cpu[k] += _cpu() - c0
                        ms[k].append(1e3 * sum(float(t[s] or 0.0) for s in ("upload", "draw", "finish")))
            base = np.min(ms["empty"])
            cbase = cpu["empty"] / repeat * 1e3
            out.append(f"  {name} ({stats['props']:,} prop/solid triangles, {stats['props_instances']} instances, "
                       f"selection {sel_ms:.2f} ms):")
            for k, v in ms.items():
                c = cpu[k] / repeat * 1e3
                out.append(f"    {k:>13}: min {np.min(v):6.2f} ms, median {np.median(v):6.2f} ms, CPU {c:6.2f} ms"
                           + ("" if k == "empty" else f"  (min - empty: {np.min(v) - base:5.2f} ms, "
                                                      f"CPU - empty: {c - cbase:5.2f} ms)"))
    return out


def main(argv=None) -> int:
    from crowd.scene import parse_size

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args(argv)
    size = parse_size(args.size)
    if size is None:
        ap.error(f"--size: expected WxH, got {args.size!r}")
    os.environ.setdefault("CROWD_CACHE_DIR", tempfile.mkdtemp(prefix="bench-props-"))
    print(f"bench_props: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.1f}, {size[0]}x{size[1]}")
    print("chain build (no cache):")
    print("\n".join(chains()))
    print("props LOD along quickstart's camera path (selection only):")
    print("\n".join(props_lod()))
    print(f"world drawn alone ({args.repeat} frames of each kind, interleaved):")
    print("\n".join(world_draw(size, max(1, args.repeat))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
