"""The ``crowd`` command line.

    crowd run SCENE [--frames N] [--size WxH] [--out DIR] [--png-every K] [--video] [--explain-lod] [--quiet]
    crowd validate SCENE
    crowd info ASSET            # a .glb/.gltf file or generator:humanoid:5000
    crowd fly SCENE [--size WxH] [--out DIR] [--record PATH] [--frames N] [--budget MS]
    crowd report SCENE... [--sweep KEY=V1,V2,...]... [--frames N] [--size WxH] [--out DIR] [--sample-every K]
                 [--compare BASELINE_DIR] [--repeat N] [--cluster local|none|tcp://HOST:PORT] [--reference-samples K]
                 [--quiet]
    crowd calibrate [--quick] [--size WxH] [--no-save]
    crowd build ASSET... [--mode points|clusters|triangles|auto|all] [--cluster local|none|tcp://HOST:PORT] [--quiet]
                [--no-calibrate]
    crowd inspect ASSET [--png FILE] [--clip NAME] [--time S] [--pose K] [--poe P] [--camera X,Y,Z] [--size WxH]
                  [--clustering error-aware|octree]

Bad input (scene, asset, parameter) is reported as one line on stderr with exit
code 2 and no traceback; nothing is written. Unexpected exceptions keep their
traceback: they are bugs and must be visible.
"""
from __future__ import annotations

import argparse
import os
import signal
import sys

from crowd.errors import CrowdError, user_errors

# numba's OpenMP worker threads spin between parallel regions by default (libgomp reads this when it loads, at
# the first parallel kernel): on a machine shared with other work the spinning takes the cores the kernels
# need. PASSIVE (they sleep) unless the user's environment says otherwise.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

#: exit code for bad user input (also argparse's)
EXIT_USAGE = 2
#: exit code after an interrupt (Ctrl-C / SIGTERM), as shells report it
EXIT_INTERRUPTED = 130


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return v


def _nonneg_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}")
    return v


def _budget(text: str) -> float:
    from crowd.fly_budget import parse_budget

    try:
        return parse_budget(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _size(text: str) -> tuple:
    from crowd.scene import SIZE_RANGE, parse_size

    s = parse_size(text)
    if s is None:
        raise argparse.ArgumentTypeError(f"expected WxH with integers in {SIZE_RANGE[0]} ..= {SIZE_RANGE[1]} "
                                         f"(e.g. 1280x720), got {text!r}")
    return s


class _Parser(argparse.ArgumentParser):
    """argparse with bad usage said in one line (exit 2), as every other bad input is; ``--help`` shows the
    usage (its subcommands' parsers are of this class too)."""

    def error(self, message):
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (`{self.prog} --help` lists the options)\n")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="crowd", description="Crowd simulation and LOD rendering sandbox.")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    r = sub.add_parser("run", help="simulate and render a scene headless, writing frames and telemetry")
    r.add_argument("scene", metavar="SCENE", help="scene file (.toml), see docs/scenes.md")
    r.add_argument("--frames", type=_positive_int, help="frames to run (overrides the scene's `frames`)")
    r.add_argument("--size", type=_size, help="image size WxH (overrides [render] size)")
    r.add_argument("--out", metavar="DIR", help="output directory (overrides [output] dir); replaced atomically")
    r.add_argument("--png-every", type=_nonneg_int, metavar="K",
                   help="write every K-th frame as PNG, 0 = none (overrides [render] png_every)")
    r.add_argument("--video", action="store_true", default=None,
                   help="also write every frame as video.mp4 (H.264, yuv420p; odd sizes padded by one pixel)")
    r.add_argument("--explain-lod", action="store_true",
                   help="mode auto: print per frame the plan drawn and why (each group's representations, "
                   "predicted against measured time, the online fit's per-unit costs); also written to "
                   "explain_lod.jsonl in the output directory")
    r.add_argument("--quiet", "-q", action="store_true", help="no progress bars or summary")

    v = sub.add_parser("validate", help="check a scene file in full and print a short summary")
    v.add_argument("scene", metavar="SCENE")

    i = sub.add_parser("info", help="describe a character: joints, clips, vertices, triangles, bounds")
    i.add_argument("asset", metavar="ASSET", help="a .glb/.gltf file or generator:NAME[:TRIANGLES[:SEED]]")

    f = sub.add_parser("fly", help="fly through a running scene in a window (glfw; H shows the controls)")
    f.add_argument("scene", metavar="SCENE", help="scene file (.toml), see docs/scenes.md")
    f.add_argument("--size", type=_size, help="window size WxH (overrides [render] size)")
    f.add_argument("--out", metavar="DIR", help="folder for screenshots and camera recordings "
                   "(default: the scene's output dir + '-fly')")
    f.add_argument("--record", metavar="PATH", help="camera recording file written by R (default: timestamped)")
    f.add_argument("--frames", type=_positive_int, help="close after N frames (scripted runs)")
    f.add_argument("--budget", type=_budget, metavar="MS",
                   help="frame budget in ms of selection + rendering (default 70): a scene whose mode misses it is "
                   "drawn in mode auto under it; 0 draws the scene's mode as written")

    rp = sub.add_parser("report", help="frame-time and accuracy report (HTML) over scenes and swept settings")
    rp.add_argument("scenes", nargs="+", metavar="SCENE", help="scene files (.toml)")
    rp.add_argument("--sweep", action="append", default=[], metavar="KEY=V1,V2,...",
                    help="sweep a setting: lod.mode, lod.poe, lod.splat_size, any lod.<key>, render.size "
                    "(alias resolution, values WxH), render.shadows (none,blob,map), render.shadow_map_size, "
                    "render.shadow_distance; repeat for a cartesian product")
    rp.add_argument("--frames", type=_positive_int, help="frames per run (overrides each scene's `frames`)")
    rp.add_argument("--size", type=_size, help="image size WxH (overrides [render] size)")
    rp.add_argument("--out", metavar="DIR", default="out/report", help="report directory (replaced atomically; "
                    "default out/report)")
    rp.add_argument("--sample-every", type=_positive_int, metavar="K",
                    help="compare every K-th frame with its reference (default: frames // 4)")
    rp.add_argument("--reference-samples", metavar="K", default="4",
                    help="the reference is full detail drawn with K x K samples per pixel and box-filtered down "
                    "(2 to 8, default 4; cached, so a second report of a scene does not draw it again)")
    rp.add_argument("--compare", metavar="BASELINE_DIR", help="flag frame-time regressions against an earlier "
                    "report directory (exit code 1 when one is found)")
    rp.add_argument("--repeat", type=_positive_int, metavar="N", help="timed runs per setting (default 3 with "
                    "--compare, else 1)")
    rp.add_argument("--cluster", metavar="ADDRESS", default="local",
                    help="where the runs and image errors run, on dask.distributed: 'local' (default: an embedded "
                    "LocalCluster on loopback), tcp://HOST:PORT of a running scheduler, or 'none' (this process); "
                    "timed runs run one at a time per machine with nothing else running")
    rp.add_argument("--quiet", "-q", action="store_true", help="no progress bar or summary")

    b = sub.add_parser("build", help="build the LOD hierarchies of many characters into the cache, on a dask cluster")
    b.add_argument("assets", nargs="+", metavar="ASSET", help="a scene (.toml: all its characters, with its fps and "
                   "[lod] keys), a .glb/.gltf file or generator:NAME[:TRIANGLES[:SEED]] (30 fps, mode defaults)")
    b.add_argument("--mode", default="all", help="LOD modes to build: points, clusters, triangles, auto, a "
                   "comma-separated list, or all (default)")
    b.add_argument("--cluster", metavar="ADDRESS", default="local", help="'local' (default: an embedded dask "
                   "LocalCluster on loopback), tcp://HOST:PORT of a running scheduler (its workers write to this "
                   "machine's cache path: share it), or 'none' (this process)")
    b.add_argument("--quiet", "-q", action="store_true", help="no progress bar or summary")
    b.add_argument("--no-calibrate", action="store_true", help="with mode auto: do not measure this machine's "
                   "frame costs when none are stored (crowd calibrate --quick, a few seconds after the builds)")

    c = sub.add_parser("calibrate", help="measure this machine's frame-cost model (about 2-3 minutes; "
                       "--quick for about half) and store it")
    c.add_argument("--quick", action="store_true", help="fewer, shorter measurements (about half the time)")
    c.add_argument("--size", type=_size, default=(1280, 720), help="image size WxH (default 1280x720)")
    c.add_argument("--no-save", action="store_true", help="print the fit without storing it")

    ins = sub.add_parser("inspect", help="show a character's VDR-AM cluster hierarchy (pyvista): clusters, "
                         "deformation levels, the cut a view selects; on screen or --png FILE",
                         description="Three views of a skinned character's cluster hierarchy: leaf clusters "
                         "coloured (VDR-AM Fig. 7), deformation level per cluster and the LOD cut a view selects "
                         "at --poe, coloured by cluster height (Fig. 11). Needs pyvista.")
    ins.add_argument("asset", metavar="ASSET", help="a skinned .glb/.gltf file or generator:NAME[:TRIANGLES[:SEED]] "
                     "(e.g. generator:humanoid:20000)")
    ins.add_argument("--png", metavar="FILE", help="write the image to FILE (.png, off screen) instead of a window")
    ins.add_argument("--clip", metavar="NAME", help="clip of the pose shown (default: the first clip)")
    ins.add_argument("--time", type=float, metavar="SECONDS", help="time in the clip (default 0)")
    ins.add_argument("--pose", type=_nonneg_int, metavar="K",
                     help="show the hierarchy's K-th representative pose (section 4.1) instead of --clip/--time")
    ins.add_argument("--poe", type=float, default=1.0, help="pixels of error of the cut shown (default 1)")
    ins.add_argument("--camera", type=_vec3, metavar="X,Y,Z",
                     help="eye position in model space, metres (default: in front at 2.5 model sizes)")
    ins.add_argument("--size", type=_size, help="image size WxH (default 1500x600)")
    ins.add_argument("--clustering", choices=("error-aware", "octree"), default="error-aware",
                     help="leaf clustering of the hierarchy (default error-aware)")
    return p


def _vec3(text: str) -> tuple:
    try:
        v = tuple(float(x) for x in text.split(","))
    except ValueError:
        v = ()
    if len(v) != 3 or not all(abs(x) < float("inf") for x in v):
        raise argparse.ArgumentTypeError(f"expected three finite numbers X,Y,Z, got {text!r}")
    return v


def cmd_inspect(args) -> int:
    from crowd.inspect import main as inspect_main

    return inspect_main(args)


def cmd_build(args) -> int:
    from crowd.build import build_assets, parse_modes, summary

    res = build_assets(args.assets, parse_modes(args.mode), cluster=args.cluster, quiet=args.quiet,
                       calibrate=not args.no_calibrate)
    if not args.quiet:
        print(summary(res))
    return 0


def cmd_calibrate(args) -> int:
    from crowd.calibrate import calibrate, summary

    model, path = calibrate(size=args.size, quick=args.quick, save=not args.no_save)
    print(summary(model, path))
    return 0


def cmd_report(args) -> int:
    from crowd.reference import check_k
    from crowd.report.pipeline import build_report
    from crowd.report.settings import parse_sweep

    sweeps = [parse_sweep(t) for t in args.sweep]
    keys = [k for k, _ in sweeps]
    dup = next((k for k in keys if keys.count(k) > 1), None)
    if dup is not None:
        from crowd.report.settings import SweepError

        raise SweepError(f"--sweep {dup}: given more than once; list all its values in one --sweep")
    baseline = None
    if args.compare is not None:
        from crowd.report.compare import load_baseline

        baseline = load_baseline(args.compare)  # read before --out may replace the same directory
    res = build_report(args.scenes, sweeps, frames=args.frames, size=args.size, out=args.out,
                       sample_every=args.sample_every, quiet=args.quiet, repeat=args.repeat, baseline=baseline,
                       baseline_dir=args.compare, cluster=args.cluster,
                       reference_samples=check_k(args.reference_samples, "--reference-samples"))
    if not args.quiet:
        n = sum(len(s["settings"]) for s in res.data["scenes"])
        print(f"wrote {res.out_dir / 'index.html'}: {len(res.data['scenes'])} scene(s), {n} setting(s)")
    cmp_ = res.data.get("compare")
    if cmp_ is not None:
        for r in cmp_["rows"]:
            if r["regression"]:
                print(f"REGRESSION {r['scene']} [{r['label']}]: {r['current_ms']:.3f} ms vs baseline "
                      f"{r['baseline_ms']:.3f} ms (x{r['ratio']:.3f} > 1 + {r['threshold']:.3f})")
        if not args.quiet or cmp_["regressions"]:
            print(f"compare with {args.compare}: {cmp_['regressions']} regression(s) in {len(cmp_['rows'])} "
                  f"compared setting(s)")
        return 1 if cmp_["regressions"] else 0
    return 0


def cmd_fly(args) -> int:
    from crowd.fly import fly

    return fly(args.scene, size=args.size, out=args.out, record=args.record, frames=args.frames, budget=args.budget)


def cmd_run(args) -> int:
    from crowd.engine import Engine
    from crowd.output import check_output_dir
    from crowd.scene import load_scene

    scene = load_scene(args.scene).with_overrides(frames=args.frames, size=args.size, out=args.out,
                                                  png_every=args.png_every, video=args.video)
    check_output_dir(scene.output_dir)  # before the (possibly long) build
    if scene.video:
        from crowd.video import ffmpeg_exe

        ffmpeg_exe()  # a missing encoder is a one-line error before the build
    if args.explain_lod and scene.lod_mode != "auto":
        raise CrowdError(f"{scene.path}: --explain-lod explains the choices of LOD mode auto; the scene's "
                         f"[lod] mode is {scene.lod_mode!r}")
    with Engine(scene, quiet=args.quiet or args.explain_lod) as engine:
        if not args.quiet:
            from crowd.start_check import start_warnings

            for line in start_warnings(scene, engine.plan.state, engine.plan.agents_per_placement):
                print(line, file=sys.stderr)
        if args.explain_lod:
            engine.explain_lod = (lambda text: None) if args.quiet else (lambda text: print(text, flush=True))
        result = engine.run()
    if not args.quiet:
        print(result.report())
    return 0


def cmd_validate(args) -> int:
    from crowd.plan import plan
    from crowd.scene import load_scene

    scene = load_scene(args.scene)
    p = plan(scene)
    print(f"OK {args.scene}: scene {scene.name!r}")
    for line in p.summary_lines():
        print("  " + line)
    from crowd.start_check import start_warnings

    for line in start_warnings(scene, p.state, p.agents_per_placement):  # valid, but frame 0 shows it
        print(line, file=sys.stderr)
    from crowd.memory import estimate_scene

    print("  " + estimate_scene(scene, p.characters).line())
    return 0


def cmd_info(args) -> int:
    from crowd.characters import build_character, parse_asset

    spec = parse_asset(args.asset)
    ch = build_character(spec)
    from sim.describe import describe

    print(format_description(args.asset, describe(ch)))
    from lod.points.paths import describe_path

    for line in describe_path(ch, {}):  # mode points: which path, why, and what it costs
        print("  " + line)
    return 0


def format_description(title: str, d: dict, indent: int = 0) -> str:
    """Render a ``sim.describe.describe`` dict as indented ``key: value`` lines."""
    lines = [title] if indent == 0 else []
    pad = "  " * (indent + 1)
    for k, v in d.items():
        if isinstance(v, dict):
            lines.append(f"{pad}{k}:")
            lines.append(format_description("", v, indent + 1))
        elif k == "notes" and isinstance(v, list):
            lines.extend(f"{pad}note: {x}" for x in v)  # one line each, none when nothing was repaired
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            lines.append(f"{pad}{k}: {len(v)}")
            for x in v:
                lines.append(f"{pad}  - " + ", ".join(f"{a}={_fmt(b)}" for a, b in x.items()))
        else:
            lines.append(f"{pad}{k}: {_fmt(v)}")
    return "\n".join(x for x in lines if x)


def _fmt(v) -> str:
    if isinstance(v, list) and len(v) > 8 and all(isinstance(x, str) for x in v):
        return ", ".join(v[:8]) + f", ... ({len(v)} in all)"
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, (list, tuple)) and v and all(isinstance(x, float) for x in v):
        return "[" + ", ".join(f"{x:.4g}" for x in v) + "]"
    if isinstance(v, (list, tuple)) and v and all(isinstance(x, (list, tuple)) for x in v):
        return "[" + ", ".join(_fmt(list(x)) for x in v) + "]"
    return str(v)


COMMANDS = {"run": cmd_run, "validate": cmd_validate, "info": cmd_info, "fly": cmd_fly, "report": cmd_report,
            "calibrate": cmd_calibrate}
COMMANDS["inspect"] = cmd_inspect
COMMANDS["build"] = cmd_build


def main(argv=None) -> int:
    """Entry point of the ``crowd`` console script and ``python -m crowd``; returns the exit code."""
    args = build_parser().parse_args(argv)  # argparse errors exit 2
    from crowd.errors import on_interrupt, reset_interrupt

    reset_interrupt()  # an interrupt of an earlier command in this process was handled there
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, on_interrupt)  # so temporary outputs are cleaned up
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, on_interrupt)  # latched: a frame loop stops even if a library swallowed it
    try:
        return COMMANDS[args.command](args)
    except user_errors() as e:
        code = getattr(e, "exit_code", EXIT_USAGE)
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        print(f"crowd {args.command}: error: {msg}", file=sys.stderr)
        return code
    except KeyboardInterrupt:
        print(f"crowd {args.command}: interrupted; nothing was written", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # `crowd validate SCENE | head`: the reader left; not an error of ours
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # so the interpreter's final flush does not fail again
        return 0


if __name__ == "__main__":
    sys.exit(main())
