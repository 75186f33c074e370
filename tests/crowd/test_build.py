"""``crowd build``: LOD hierarchies built ahead of time on a dask cluster, found warm by a later run."""
import dataclasses

import pytest
from crowd_testutil import REPO, run_cli, tiny_scene

from crowd.build import CACHED_MODES, expand_assets, parse_modes
from crowd.errors import CrowdError

SCENE = tiny_scene(replace={"mode = \"none\"": "mode = \"clusters\"\npoe = 2.0"}, append="""
[[characters]]
name = "runner"
generator = "humanoid"
triangles = 500
seed = 3
fps = 24

[[placement]]
kind = "grid"
character = "runner"
rows = 1
cols = 1
spacing = [1.0, 1.0]
""")


def test_modes_and_jobs_of_a_scene(write_scene):
    assert parse_modes("all") == CACHED_MODES
    assert parse_modes("clusters, points,clusters") == ("clusters", "points")
    for bad in ("none", "bogus", "", "all,points"):
        with pytest.raises(CrowdError, match="expected one of"):
            parse_modes(bad)
    p = write_scene(SCENE)
    jobs = expand_assets([p, "generator:humanoid:700"], ("clusters", "points"))
    assert [(j.spec.name, j.mode, j.fps) for j in jobs] == [
        ("walker", "clusters", 30), ("walker", "points", 30), ("runner", "clusters", 24), ("runner", "points", 24),
        ("humanoid", "clusters", 30), ("humanoid", "points", 30)]
    # the scene's own mode is built with its [lod] keys, the others with their defaults (as crowd run does)
    assert dict(jobs[0].params)["poe"] == 2.0 and jobs[1].params == () and jobs[4].params == ()
    assert jobs[5].spec.triangles == 700
    # a scene with hierarchical instancing: one more job per mode that caches per-group data, after the characters
    from crowd.build import _takes_instancing

    jobs = expand_assets([REPO / "scenes" / "stadium.toml"], ("points", "clusters"))
    scene_jobs = [j for j in jobs if j.spec is None]
    assert [j.mode for j in scene_jobs] == [m for m in ("points", "clusters") if _takes_instancing(m)]
    assert jobs[-len(scene_jobs) or len(jobs):] == scene_jobs and all("instancing" in j.label for j in scene_jobs)


def _cache_entries(folder):
    return {p.name: p.stat().st_mtime_ns for p in folder.iterdir()} if folder.is_dir() else {}


class _Rebuilt(Exception):
    pass


def _forbid_builds(monkeypatch):
    """Make every hierarchy build of the three cached modes raise: a run that finds its cache warm never calls
    one."""
    import lod.chains.chain
    import lod.clusters.mode
    import lod.points.follow
    import lod.points.rep

    def fail(*a, **k):
        raise _Rebuilt

    monkeypatch.setattr(lod.clusters.mode, "build_cluster_hierarchy", fail)
    monkeypatch.setattr(lod.points.rep, "build_hierarchy", fail)
    monkeypatch.setattr(lod.points.follow, "build_follow", fail)
    monkeypatch.setattr(lod.chains.chain, "build_chain", fail)


def _engine_scenes(scene):
    """The scene in each cached mode: its own mode with its [lod] keys, the others with their defaults."""
    return [scene] + [dataclasses.replace(scene, lod_mode=m, lod_params=()) for m in CACHED_MODES
                      if m != scene.lod_mode]


def test_build_on_the_cluster_then_the_run_finds_the_cache_warm(write_scene, tmp_path, monkeypatch, dask_cluster):
    from crowd.engine import Engine
    from crowd.scene import load_scene

    cache = tmp_path / "cache"
    monkeypatch.setenv("CROWD_CACHE_DIR", str(cache))  # a cold cache of its own (workers are told the path)
    p = write_scene(SCENE)
    scene = load_scene(p)
    with monkeypatch.context() as m:  # cold: a run would build (the check below can fail)
        _forbid_builds(m)
        with pytest.raises(_Rebuilt):
            Engine(dataclasses.replace(scene, lod_mode="triangles", lod_params=()), quiet=True)
    r = run_cli("build", p, "--mode", "all", "--cluster", dask_cluster, "--no-calibrate")
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().splitlines()
    assert len(lines) == 2 * len(CACHED_MODES) + 1 and "walker [clusters]" in r.stdout and "runner [auto]" in r.stdout
    assert f"on dask scheduler {dask_cluster}" in lines[-1] and str(cache) in lines[-1]
    assert not (cache / "cost_model.json").exists()  # --no-calibrate
    built = _cache_entries(cache)
    npz = [n for n in built if n.endswith(".npz")]
    assert npz and not [n for n in built if n.endswith(".tmp")]  # atomic writes leave no temporary file
    assert f"{len(npz)} new cache entries" in lines[-1]
    _forbid_builds(monkeypatch)
    for sc in _engine_scenes(scene):
        with Engine(sc, quiet=True) as eng:  # builds every representation: from the cache only
            assert len(eng.reps) >= 2
    assert _cache_entries(cache) == built  # nothing rewritten
    r = run_cli("build", p, "--mode", "clusters", "--cluster", "none", "--quiet")  # warm: nothing new
    assert r.returncode == 0 and r.stdout == "" and _cache_entries(cache) == built


@pytest.mark.parametrize("asset, msg", [
    ("missing.glb", "missing.glb: file not found"),
    ("missing.toml", "missing.toml: file not found"),
    ("model.obj", "expected a glTF file"),
    ("bad.glb", "bad.glb"),
    ("generator:nope", "generator:NAME"),
])
def test_bad_assets_are_one_sentence_exit_2(tmp_path, asset, msg):
    (tmp_path / "bad.glb").write_bytes(b"glTF\x02\x00\x00\x00")  # a truncated GLB header
    (tmp_path / "model.obj").write_text("v 0 0 0\n")
    arg = asset if asset.startswith("generator:") else tmp_path / asset
    r = run_cli("build", arg, "--mode", "clusters", "--cluster", "none", cwd=tmp_path)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and msg in lines[0] and "Traceback" not in r.stderr, r.stderr
    assert r.stdout == ""


def test_build_prints_seconds_and_megabytes_per_character(tmp_path, monkeypatch, write_scene):
    """``crowd build --mode points`` prints per character the seconds and the MB of its hierarchies: by default
    one hierarchy of samples that follow the animation (the samples, stratification poses and frames measured);
    on the per-keyframe-pair path the poses baked per clip, the pose error, and the cost per second of clip."""
    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path / "cache"))
    r = run_cli("build", "generator:humanoid:600", "--mode", "points", "--cluster", "none")
    assert r.returncode == 0, r.stderr
    line = next(x for x in r.stdout.splitlines() if "[points]" in x)
    secs, mb = line.split(": ", 1)[1].split(" (")[0].split(", ")
    assert secs.endswith(" s") and float(secs[:-2]) > 0 and mb.endswith(" MB") and float(mb[:-3]) > 0
    assert "points follow: " in line and "stratification poses" in line and "frames measured" in line
    scene = write_scene(tiny_scene(replace={'mode = "none"': 'mode = "points"\nanimation = "baked"'}), "b.toml")
    r = run_cli("build", scene, "--mode", "points", "--cluster", "none")
    assert r.returncode == 0, r.stderr
    line = next(x for x in r.stdout.splitlines() if "[points]" in x)
    assert " MB (poses per clip: " in line and "% of the extent" in line and "MB per clip second" in line
    pct = float(line.split("pose error <= ")[1].split("%")[0])
    assert 0.0 < pct <= 2.0


def test_a_build_with_mode_auto_measures_this_machine_s_costs_once(tmp_path, monkeypatch):
    """Issue 50, item 3: ``crowd build`` with mode auto measures this machine's frame costs when the cache holds
    none (crowd calibrate --quick) and stores them where a run reads them back (no longer the defaults); a second
    build keeps them; a corrupt cost file is named in one line and replaced; other modes do not calibrate."""
    from lod.auto import cost_model

    cache = tmp_path / "cache"
    monkeypatch.setenv("CROWD_CACHE_DIR", str(cache))
    r = run_cli("build", "generator:humanoid:600", "--mode", "points", "--cluster", "none")
    assert r.returncode == 0 and not (cache / cost_model.FILE_NAME).exists(), r.stderr
    assert cost_model.load_any(warn=False).is_default
    r = run_cli("build", "generator:humanoid:600", "--mode", "auto", "--cluster", "none")
    assert r.returncode == 0, r.stderr
    assert "measured this machine's frame costs for mode auto" in r.stdout and str(cache) in r.stdout
    model = cost_model.load_any(warn=False)
    assert not model.is_default and model.coefficients["triangles"] > 0 and model.samples > 0
    stamp = (cache / cost_model.FILE_NAME).stat().st_mtime_ns
    r = run_cli("build", "generator:humanoid:600", "--mode", "auto", "--cluster", "none")
    assert r.returncode == 0 and "frame costs" not in r.stdout
    assert (cache / cost_model.FILE_NAME).stat().st_mtime_ns == stamp  # kept
    (cache / cost_model.FILE_NAME).write_text("{not json")
    r = run_cli("build", "generator:humanoid:600", "--mode", "auto", "--cluster", "none")
    assert r.returncode == 0, r.stderr
    said = [ln for ln in r.stdout.splitlines() if "frame costs" in ln]
    assert len(said) == 1 and "replaced" in said[0] and cost_model.FILE_NAME in said[0]
    assert not cost_model.load_any(warn=False).is_default
