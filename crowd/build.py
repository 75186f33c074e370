"""``crowd build``: build the LOD hierarchies of many characters ahead of time, on a dask cluster.

    crowd build ASSET... [--mode points|clusters|triangles|auto|all] [--cluster local|none|tcp://HOST:PORT]
                [--no-calibrate]

ASSET is

- a scene file (``.toml``): every character of the scene, baked at its own ``fps``; the scene's own
  ``[lod] mode`` is built with the scene's ``[lod]`` keys, any other mode with that mode's defaults,
  exactly as ``crowd run`` (``crowd.engine.Engine``) builds them, so a later run of the scene finds every
  entry in the cache; a scene with the ``instancing`` effect also gets one job per mode that takes the
  simulation's instancing groups (points: the super-hierarchies of Wand & Strasser §3.6), which builds the
  scene's engine after its characters' jobs;
- a glTF file (``.glb``/``.gltf``) or ``generator:NAME[:TRIANGLES[:SEED]]`` (as ``crowd info`` takes):
  that character at 30 fps with every mode's defaults (what a scene naming it with default ``fps`` and
  ``[lod]`` keys uses).

Mode auto's costs (issue 50, item 3): a build that includes mode ``auto`` also measures this machine's per-unit
frame costs when the cache holds no calibration of it (``crowd calibrate --quick``, a few seconds, in this process
after the builds, so nothing else runs while it is timed) and stores them where a run reads them: the first
plan of a later run is priced from this machine's measured costs, not another's defaults (without them the
quickstart explored its point plan, five times dearer, for four frames). ``--no-calibrate`` skips it; a
calibration that cannot be measured is one line on stderr, and runs start from the defaults as before.

One task per (character, mode) runs the mode's own ``build`` (``lod.modes``: ``lod.points.mode``
``HierarchyCache``, ``lod.clusters.mode.cached_hierarchy``, ``lod.chains.chain.cached_chain``; ``auto`` the
triangle chains plus the candidates its keys ask for), which loads a warm entry or builds and stores it. Each
entry is written atomically by the mode (temp file in the cache folder + ``os.replace``), so concurrent tasks
and runs never read half a file, and an interrupted build leaves no entry. Mode ``none`` has nothing to build.

The tasks run on :class:`crowd.report.cluster.ClusterPool` (default: an embedded dask ``LocalCluster``, one
single-threaded worker process per core; builds are not timed, so they fill every worker). Every task writes
to this process's cache folder (``$CROWD_CACHE_DIR``, default ``~/.cache/crowd``), passed to it explicitly:
workers on other machines need that path on a shared filesystem.

Bad input (a missing or unsupported asset, an invalid scene, an unknown mode) is reported before anything
runs; a file that fails to load on a worker is reported after the other builds finished; both as one sentence
naming the file, exit code 2.
"""
from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from crowd.errors import AssetError, CrowdError, user_errors

#: LOD modes that keep hierarchies in the on-disk cache (``--mode all`` builds each)
CACHED_MODES = ("points", "clusters", "triangles", "auto")
#: environment variable of the cache folder (the same for every mode, see ``lod.clusters.mode.cache_dir``)
CACHE_ENV = "CROWD_CACHE_DIR"


@dataclass(frozen=True)
class BuildJob:
    """One task: the hierarchies of one character in one LOD mode.

    asset : the command-line argument it comes from (a scene, glTF file or generator spec)
    spec : crowd.scene.CharacterSpec of the character
    fps : int, the bake rate (the scene's ``characters[i].fps``, or 30)
    mode : LOD mode name (one of :data:`CACHED_MODES`)
    params : tuple of (key, value), the ``[lod]`` keys the mode is built with
    """

    asset: str
    spec: object
    fps: int
    mode: str
    params: tuple = field(default=())

    @property
    def label(self) -> str:
        if self.spec is None:
            return f"{Path(self.asset).name} instancing [{self.mode}]"
        return f"{self.spec.name} [{self.mode}]"


def cache_dir() -> Path:
    """The cache folder every mode writes to: ``$CROWD_CACHE_DIR`` or ``~/.cache/crowd``."""
    from lod.clusters.mode import cache_dir as cd

    return cd()


def parse_modes(text: str) -> tuple:
    """``--mode`` -> the modes to build: one of :data:`CACHED_MODES`, ``all``, or a comma-separated list.

    Raises
    ------
    crowd.errors.CrowdError
        An unknown mode (the sentence lists the accepted ones).
    """
    parts = [p.strip() for p in str(text).split(",") if p.strip()]
    if parts == ["all"]:
        return CACHED_MODES
    bad = [p for p in parts if p not in CACHED_MODES]
    if bad or not parts:
        raise CrowdError(f"--mode {text!r}: expected one of {', '.join(CACHED_MODES)} or all (mode 'none' has "
                         "no hierarchy to build)")
    return tuple(dict.fromkeys(parts))


def expand_assets(assets: list, modes: tuple) -> list:
    """The build jobs of ``assets`` (module docstring) in ``modes``, checked before anything runs.

    Raises
    ------
    crowd.errors.CrowdError
        A file that does not exist or is neither a scene (.toml) nor a glTF file, a generator spec that is
        malformed, or a scene that does not validate (one sentence naming the file).
    """
    from crowd.characters import parse_asset
    from crowd.scene import load_scene

    jobs = []
    for a in assets:
        a = str(a)
        if a.lower().endswith(".toml"):
            if not Path(a).is_file():
                raise AssetError(f"{a}: file not found; expected a scene (.toml), a glTF file (.glb, .gltf) or "
                                 "generator:NAME[:TRIANGLES[:SEED]]")
            scene = load_scene(a)
            for spec in scene.characters:
                for m in modes:
                    params = tuple(scene.lod_params) if m == scene.lod_mode else ()
                    jobs.append(BuildJob(a, spec, int(spec.fps), m, params))
            if any(e.name == "instancing" for e in scene.effects):
                # hierarchical instancing (Wand & Strasser §3.6): modes that take the simulation's instancing
                # groups cache per-group data too (points: super-hierarchies); one job per such mode builds the
                # scene's engine, after the character jobs, exactly as crowd run does
                for m in modes:
                    if _takes_instancing(m):
                        params = tuple(scene.lod_params) if m == scene.lod_mode else ()
                        jobs.append(BuildJob(a, None, 0, m, params))
        else:
            spec = parse_asset(a)
            jobs.extend(BuildJob(a, spec, int(spec.fps), m) for m in modes)
    return jobs


def _takes_instancing(mode: str) -> bool:
    import inspect

    from lod.modes import mode_module

    return "instancing" in inspect.signature(mode_module(mode).build).parameters


def build_task(job: BuildJob, cache: str, *after) -> dict:
    """Run one job (on a dask worker or in this process): build the character, then its mode's hierarchies
    through the mode's ``build``, which loads warm entries or builds and stores them atomically in ``cache``.
    ``after``: results of jobs this one waits for (ignored; dask runs it after them).

    Returns
    -------
    dict: ``label``, ``asset``, ``seconds`` (wall clock), ``reps`` (representations built); or ``error`` (one
    sentence) when the asset fails to load.
    """
    import inspect

    from crowd.characters import build_character
    from lod.modes import mode_module

    old = os.environ.get(CACHE_ENV)
    os.environ[CACHE_ENV] = str(cache)  # every mode reads its folder from here (lod.*_mode.cache_dir)
    start = time.time()
    try:
        if job.spec is None:  # a scene's instancing groups: its engine, built as crowd run builds it
            import dataclasses

            from crowd.engine import Engine
            from crowd.scene import load_scene

            with Engine(dataclasses.replace(load_scene(job.asset), lod_mode=job.mode, lod_params=job.params),
                        quiet=True) as engine:
                reps = engine.reps
        else:
            ch = build_character(job.spec)
            module = mode_module(job.mode)
            extra = {"instancing": None} if "instancing" in inspect.signature(module.build).parameters else {}
            reps, _ = module.build([ch], [job.spec.name], [job.fps], dict(job.params), progress=False, **extra)
    except user_errors() as e:
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        return {"label": job.label, "asset": job.asset, "error": msg if Path(job.asset).name in msg else f"{job.asset}: {msg}"}
    finally:
        if old is None:
            os.environ.pop(CACHE_ENV, None)
        else:
            os.environ[CACHE_ENV] = old
    seconds = time.time() - start
    return {"label": job.label, "asset": job.asset, "seconds": seconds, "reps": len(reps),
            "bytes": int(sum(int(getattr(r, "nbytes", 0) or 0) for r in reps)),
            "poses": pose_summary(reps, ch if job.spec is not None else None, seconds)}


def pose_summary(reps, character, seconds: float) -> str:
    """One line on the poses mode points baked per clip (``lod.points.poses``), with the build time and
    hierarchy bytes per second of clip; for samples that follow the animation (``lod.points.follow``) the
    path and the frames measured; "" for other representations."""
    parts = []
    for r in reps:
        if getattr(r, "follow", False):
            st = r.tree.stats
            parts.append(f"points follow: {r.n_points:,} samples, {st.get('poses', 0)} stratification poses, "
                         f"{st.get('frames', 0)} frames measured")
            continue
        poses = getattr(r, "poses", None)
        if not poses or character is None:
            continue
        from lod.points.poses import character_extent

        dur = sum(float(character.clip(n).duration) for n in poses)
        clips = ", ".join(f"{n} {len(cp.times)}" + (" (capped)" if cp.capped else "") for n, cp in poses.items())
        err = 100.0 * max(cp.error for cp in poses.values()) / character_extent(character)
        line = f"poses per clip: {clips}; pose error <= {err:.2g} % of the extent"
        if dur > 0:
            line += f"; {seconds / dur:.2g} s and {r.nbytes / dur / 1e6:.3g} MB per clip second"
        parts.append(line)
    return "; ".join(parts)


def _entries(folder: Path) -> set:
    """Names of the cache entries (``*.npz``) in ``folder``."""
    try:
        return {p.name for p in folder.iterdir() if p.suffix == ".npz"}
    except OSError:
        return set()


@dataclass
class BuildResult:
    """What :func:`build_assets` did: one result dict per job (:func:`build_task`), the cache folder, the
    entries it gained, where it ran, and the wall-clock seconds."""

    results: list
    cache: Path
    new_entries: list
    cluster: str
    seconds: float
    #: what mode auto's calibration did (:func:`calibrate_if_missing`; None: nothing)
    calibration: str | None = None


def build_assets(assets: list, modes: tuple = CACHED_MODES, cluster: str | None = "local",
                 quiet: bool = False, calibrate: bool = True) -> BuildResult:
    """Build the hierarchies of every character of ``assets`` in ``modes`` (module docstring).

    Parameters
    ----------
    assets : scene files, glTF files or generator specs
    modes : LOD modes (:func:`parse_modes`)
    cluster : ``"local"`` (embedded LocalCluster), ``"none"``/None (this process) or ``tcp://HOST:PORT``
    quiet : no progress bar
    calibrate : with mode auto among the jobs, measure this machine's costs when none are stored
        (:func:`calibrate_if_missing`)

    Raises
    ------
    crowd.errors.CrowdError
        Bad input (before anything runs), or the first asset that failed to load on a worker (after the
        other builds finished; message ``FILE: reason``).
    """
    from tqdm import tqdm

    from crowd.report.cluster import ClusterPool

    jobs = expand_assets(assets, modes)
    pool = ClusterPool(cluster)
    cache = cache_dir()
    try:
        cache.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise CrowdError(f"{CACHE_ENV}={cache}: cannot create the cache folder ({e.strerror}); expected a "
                         "writable folder") from None
    before = _entries(cache)
    t0 = time.time()
    with pool, tqdm(total=len(jobs), desc="build", unit="hierarchy", disable=quiet or not sys.stderr.isatty(),
                    leave=False, file=sys.stderr, dynamic_ncols=True) as bar:
        # an "auto" job reuses the chains, clusters and points of its character's other jobs: it runs after them
        # instead of building the same entries at the same time
        # a scene's instancing job reuses its characters' hierarchies of the same mode: it runs after those
        handles = []
        for j in jobs:
            if j.spec is None:
                after = [h for i, h in enumerate(handles) if jobs[i].asset == j.asset and jobs[i].mode == j.mode]
            else:
                after = [h for i, h in enumerate(handles) if j.mode == "auto" and jobs[i].mode != "auto"
                         and (jobs[i].asset, jobs[i].spec) == (j.asset, j.spec)]
            handles.append(pool.submit(build_task, j, str(cache), *after))
        results = pool.results(handles, done=lambda: bar.update(1))
        description = pool.description
    bad = [r for r in results if "error" in r]
    if bad:
        # one sentence: the first failure; the modes of one broken file fail alike, so only other causes count
        others = len(dict.fromkeys(r["error"] for r in bad)) - 1
        ok = len(results) - len(bad)
        more = ([f"{others} other failure{'s' if others > 1 else ''}"] if others else []) + \
            ([f"{ok} other build{'s are' if ok > 1 else ' is'} in the cache"] if ok else [])
        raise AssetError(bad[0]["error"] + (f" ({'; '.join(more)})" if more else ""))
    seconds = time.time() - t0
    cal = calibrate_if_missing() if calibrate and any(j.mode == "auto" for j in jobs) else None
    return BuildResult(results, cache, sorted(_entries(cache) - before), description, seconds, cal)


def calibrate_if_missing() -> str | None:
    """Measure and store this machine's cost model (``crowd calibrate --quick``) when the cache holds none of this
    host (module docstring); a file that cannot be used (corrupt, another format) is replaced. Returns a line
    saying what was done, None when a calibration is stored. A measurement that fails is one line on stderr."""
    from lod.auto import cost_model

    model, problem = cost_model.load_checked(key="")
    if not model.is_default and problem is None:
        return None
    from crowd.calibrate import calibrate

    t0 = time.time()
    try:
        _, path = calibrate(quick=True, save=True)
    except Exception as e:  # the hierarchies are built; mode auto falls back to the defaults
        print(f"crowd build: warning: mode auto's costs could not be measured ({type(e).__name__}: {e}); runs "
              "start from the defaults (crowd calibrate measures them)", file=sys.stderr)
        return None
    why = f"; {cost_model.FILE_NAME} {problem}, replaced" if problem else ""
    return (f"measured this machine's frame costs for mode auto in {time.time() - t0:.1f} s (crowd calibrate "
            f"--quick{why}): {path}")


def summary(res: BuildResult) -> str:
    """Lines for the terminal: one per job, then the totals."""
    lines = [f"  {r['label']}: {r['seconds']:.1f} s, {r.get('bytes', 0) / 1e6:.1f} MB"
             + (f" ({r['poses']})" if r.get("poses") else "") for r in res.results]
    lines.append(f"built {len(res.results)} hierarchy set(s) in {res.seconds:.1f} s on {res.cluster}; "
                 f"{len(res.new_entries)} new cache entr{'y' if len(res.new_entries) == 1 else 'ies'} in {res.cache}")
    if res.calibration:
        lines.append(res.calibration)
    return "\n".join(lines)


__all__ = ["CACHED_MODES", "BuildJob", "BuildResult", "build_assets", "build_task", "cache_dir", "calibrate_if_missing",
           "expand_assets",
           "parse_modes", "pose_summary", "summary"]
