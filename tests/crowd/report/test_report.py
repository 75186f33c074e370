"""``crowd report`` and the image metrics behind it."""
import json
import math
import re

import numpy as np
import pytest
from crowd_testutil import run_cli, tiny_scene

from crowd import image_metrics as im
from crowd.errors import CrowdError, SceneError
from crowd.report.metrics import aggregate, pareto_front
from crowd.report.runs import read_frames_csv
from crowd.report.settings import expand_settings, parse_sweep

# exact animation times (``pose_rate = 0``, lod.poses): its mode-none setting is the full-detail reference itself
REPORT_SCENE = tiny_scene(replace={"frames = 3": "frames = 6", "size = [64, 48]": "size = [96, 72]",
                                   "png_every = 1": "png_every = 0", 'mode = "none"': 'mode = "none"\npose_rate = 0'})


# ---------------------------------------------------------------------------------------------------- image metrics
def _img(seed=0, shape=(40, 50, 3)):
    return np.random.default_rng(seed).integers(0, 256, shape, dtype=np.uint8)


def test_identical_images_are_perfect():
    a = _img()
    assert im.psnr(a, a) == math.inf
    assert im.ssim(a, a) == 1.0
    m = im.compare(a, a)
    assert m["identical"] and m["ssim"] == 1.0
    if im.flip_available():
        assert m["flip"] == pytest.approx(0.0, abs=1e-6)
    assert m["error_map"].shape == (40, 50, 3) and np.all(np.isfinite(m["error_map"]))


def test_psnr_matches_formula():
    a = np.zeros((8, 8, 3), np.uint8)
    b = a.copy()
    b[0, 0, 0] = 255  # one full-scale error in 192 values: MSE = 1/192
    assert im.psnr(b, a) == pytest.approx(10 * math.log10(192))


def test_ssim_orders_distortions_and_is_symmetric():
    a = _img(1).astype(np.float64) / 255
    rng = np.random.default_rng(2)
    small = np.clip(a + rng.normal(0, 0.02, a.shape), 0, 1)
    big = np.clip(a + rng.normal(0, 0.2, a.shape), 0, 1)
    s_small, s_big = im.ssim(small, a), im.ssim(big, a)
    assert 1.0 > s_small > s_big > -1.0
    assert im.ssim(a, small) == pytest.approx(s_small)
    # a constant image against itself shifted: SSIM reduces to the luminance term of Wang et al. eq. 6
    c, d = np.full((16, 16, 3), 0.5), np.full((16, 16, 3), 0.6)
    c1 = (im.SSIM_K1) ** 2
    assert im.ssim(c, d) == pytest.approx((2 * 0.5 * 0.6 + c1) / (0.25 + 0.36 + c1))


def test_metrics_refuse_bad_inputs():
    with pytest.raises(ValueError, match="shapes differ"):
        im.psnr(_img(shape=(4, 4, 3)), _img(shape=(4, 5, 3)))
    bad = np.zeros((4, 4, 3))
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        im.ssim(bad, np.zeros((4, 4, 3)))


@pytest.mark.skipif(not im.flip_available(), reason="flip-evaluator is not installed (pip install flip-evaluator)")
def test_flip_grows_with_error():
    a = _img(3).astype(np.float64) / 255
    small = np.clip(a + 0.02, 0, 1)
    big = np.clip(a + 0.3, 0, 1)
    f_small, _ = im.flip(small, a)
    f_big, fmap = im.flip(big, a)
    assert 0.0 < f_small < f_big <= 1.0
    assert fmap.shape == a.shape and fmap.dtype == np.float32


# --------------------------------------------------------------------------------------------------- sweeps, pareto
def test_parse_sweep_values():
    assert parse_sweep("lod.mode=none,points") == ("lod.mode", ["none", "points"])
    assert parse_sweep("lod.poe=0.5,2") == ("lod.poe", [0.5, 2])
    assert parse_sweep("resolution=96x72,64x48") == ("render.size", [[96, 72], [64, 48]])
    for bad, msg in [("lod.foo=1", "unknown key"), ("sim.dt=1", "unknown key"), ("lod.poe", "KEY=V1"),
                     ("lod.poe=1,,2", "empty value"), ("render.size=3x3", "bad size"), ("lod.poe=1,1", "repeated")]:
        with pytest.raises(CrowdError, match=msg):
            parse_sweep(bad)


def test_expand_settings_drops_keys_a_mode_does_not_take(write_scene):
    p = write_scene(REPORT_SCENE)
    sets = expand_settings(p, [parse_sweep("lod.mode=none,clusters"), parse_sweep("lod.poe=0.5,2")])
    assert [s.label for s in sets] == ["lod.mode=none", "lod.mode=clusters, lod.poe=0.5",
                                       "lod.mode=clusters, lod.poe=2"]
    assert dict(sets[2].scene.lod_params)["poe"] == 2.0
    with pytest.raises(SceneError, match="lod.poe"):
        expand_settings(p, [parse_sweep("lod.mode=clusters"), parse_sweep("lod.poe=-1")])
    with pytest.raises(CrowdError, match="accepts 'poe'"):
        expand_settings(p, [parse_sweep("lod.poe=1,2")])  # the scene's mode is none


def test_pareto_front_and_aggregate():
    assert pareto_front([1.0, 2.0, 3.0, 2.5], [0.5, 0.2, 0.3, 0.1]) == [0, 1, 3]
    assert pareto_front([1.0, 1.0], [0.3, 0.2]) == [1]
    a = aggregate([{"mse": 0.0, "ssim": 1.0, "flip": 0.0, "identical": True}] * 2)
    assert a["psnr"] == math.inf and a["identical"]
    b = aggregate([{"mse": 0.01, "ssim": 0.9, "flip": 0.1, "identical": False},
                   {"mse": 0.0, "ssim": 1.0, "flip": 0.0, "identical": True}])
    assert b["psnr"] == pytest.approx(10 * math.log10(200)) and b["ssim"] == pytest.approx(0.95)


# --------------------------------------------------------------------------------------------------- the whole report
def test_report_of_a_tiny_scene_with_a_two_value_sweep(write_scene, tmp_path):
    scene = write_scene(REPORT_SCENE)
    out = tmp_path / "rep"
    r = run_cli("report", scene, "--sweep", "lod.mode=none,clusters", "--out", out, "--sample-every", "2",
                "--cluster", "none", "--quiet")
    assert r.returncode == 0, r.stderr
    page = (out / "index.html").read_text()
    data = json.loads((out / "report.json").read_text())
    # every image the page names exists, and every plot and sample written is on the page
    srcs = set(re.findall(r"<img src='([^']+)'", page))
    assert srcs and all((out / s).is_file() for s in srcs)
    written = {p.relative_to(out).as_posix() for d in ("plots", "samples") for p in (out / d).glob("*.png")}
    assert written == srcs
    (sc,) = data["scenes"]
    assert [s["label"] for s in sc["settings"]] == ["lod.mode=none", "lod.mode=clusters"]
    assert page.count("<tr class='setting'>") == 2
    for s in sc["settings"]:
        assert [m["frame"] for m in s["samples"]] == [0, 2, 4]
        for q in ("p50", "p95", "p99", "max"):
            assert math.isfinite(s["frame_ms"][q]) and s["frame_ms"][q] > 0
        assert s["frame_ms"]["p50"] <= s["frame_ms"]["p95"] <= s["frame_ms"]["p99"] <= s["frame_ms"]["max"]
        for m in s["samples"]:
            assert 0.0 <= m["ssim"] <= 1.0 and (m["flip"] is None or 0.0 <= m["flip"] <= 1.0)
            assert m["psnr"] is None or math.isfinite(m["psnr"])  # None = identical (inf)
    nolod, clusters = sc["settings"]
    # the mode-none setting is aliased full detail: identical to itself, not to the supersampled reference
    assert nolod["aliased_full_detail"] and not clusters["aliased_full_detail"]
    assert nolod["accuracy_aliased"]["identical"] and nolod["accuracy_aliased"]["psnr"] is None  # inf
    assert nolod["accuracy_aliased"]["ssim"] == 1.0
    assert all(m["aliased"]["psnr"] is None and m["aliased"]["ssim"] == 1.0 for m in nolod["samples"])
    assert not nolod["accuracy"]["identical"] and 15.0 < nolod["accuracy"]["psnr"] < 60.0
    assert clusters["triangles"] <= nolod["triangles"] and clusters["triangles"] > 0
    assert clusters["accuracy"]["psnr"] is None or 10.0 < clusters["accuracy"]["psnr"]
    assert clusters["accuracy_aliased"]["psnr"] is None or 10.0 < clusters["accuracy_aliased"]["psnr"]
    # the page's figures as text beside it (crowd.report.table)
    import csv

    table = list(csv.DictReader((out / "table.csv").open()))
    assert [(r["setting"], r["runs"]) for r in table] == [("lod.mode=none", "1"), ("lod.mode=clusters", "1")]
    assert float(table[1]["psnr_db"]) == pytest.approx(clusters["accuracy"]["psnr"]) or clusters["accuracy"]["psnr"] is None
    assert float(table[0]["first_frame_ms"]) == pytest.approx(nolod["frame_ms"]["max"], rel=0.5)
    md = (out / "table.md").read_text()
    assert md.count("| tiny |") == 2 and "one run" in md and "4 x 4 samples per pixel" in md
    (ref,) = sc["reference"]
    assert ref["k"] == 4 and ref["size"] == [96, 72] and ref["frames"] == 6 and ref["drawn"] + ref["cached"] == 6
    assert data["reference"]["k"] == 4 and "box filter" in data["reference"]["filter"] and "4 x 4 samples" in page
    assert sc["pareto_front"][0] in ("s0", "s1")
    assert data["machine"]["cpu"] and "∞ (identical)" in page
    assert (out / "runs" / sc["slug"] / "s0" / "summary.json").is_file()
    # frame time = sum of the stages (PNG writes of the sampled frames left out), from the run's frames.csv
    cols = read_frames_csv(out / "runs" / sc["slug"] / "s1" / "frames.csv")
    ft = sum(cols[k] for k in ("simulate", "select", "upload", "draw", "finish")) * 1e3
    assert clusters["frame_ms"]["max"] == pytest.approx(ft.max()) and np.all(ft <= cols["total"] * 1e3 + 1e-9)
    assert not list(tmp_path.glob(".rep*"))  # no temporary directories left


def test_reference_run_when_no_setting_is_nolod(write_scene, tmp_path):
    scene = write_scene(REPORT_SCENE.replace("frames = 6", "frames = 2"))
    out = tmp_path / "rep"
    r = run_cli("report", scene, "--sweep", "lod.mode=clusters", "--sweep", "resolution=64x48,80x60",
                "--out", out, "--cluster", "none", "--quiet")
    assert r.returncode == 0, r.stderr
    data = json.loads((out / "report.json").read_text())
    (sc,) = data["scenes"]
    # aliased full detail added at each size, as a setting like any other
    assert [(s["label"], s["size"]) for s in sc["settings"]] == [
        ("lod.mode=clusters, render.size=64x48", [64, 48]), ("lod.mode=clusters, render.size=80x60", [80, 60]),
        ("full detail (aliased), render.size=64x48", [64, 48]), ("full detail (aliased), render.size=80x60", [80, 60])]
    assert sorted(p.name for p in (out / "runs" / sc["slug"]).iterdir()) == [
        "reference_64x48", "reference_80x60", "s0", "s1", "s2", "s3"]
    for s in sc["settings"]:
        assert len(s["samples"]) == 2 and all(0.0 < m["ssim"] <= 1.0 for m in s["samples"])
    assert [s["aliased_full_detail"] for s in sc["settings"]] == [False, False, True, True]
    assert [r["size"] for r in sc["reference"]] == [[64, 48], [80, 60]]


@pytest.mark.parametrize("args, msg", [
    (["--sweep", "lod.nope=1,2"], "unknown key 'lod.nope'"),
    (["--sweep", "lod.mode=none,bogus"], "lod.mode"),
    (["--sweep", "lod.mode=none", "--sweep", "lod.mode=points"], "more than once"),
])
def test_bad_sweep_exit_2_nothing_written(write_scene, tmp_path, args, msg):
    scene = write_scene(REPORT_SCENE)
    out = tmp_path / "rep"
    r = run_cli("report", scene, *args, "--out", out)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and msg in lines[0] and "Traceback" not in r.stderr
    assert not out.exists() and not list(tmp_path.glob(".rep*"))


# --------------------------------------------------------------------------------------------------------- flicker
def test_flicker_cancels_motion_the_reference_shares():
    rng = np.random.default_rng(5)
    r0, r1 = rng.random((12, 10, 3)), rng.random((12, 10, 3))
    assert im.flicker(r0, r1, r0, r1) == 0.0  # the setting changes exactly as the reference
    # a constant offset of the test (a static LOD error) does not flicker either
    assert im.flicker(np.clip(r0, 0, .9) + .1, np.clip(r1, 0, .9) + .1,
                      np.clip(r0, 0, .9), np.clip(r1, 0, .9)) == pytest.approx(0.0, abs=1e-12)
    # a pop in one pixel channel of frame t+1 by 0.5: 0.5 / (12 * 10 * 3)
    t1 = r1.copy()
    t1[3, 4, 1] = r1[3, 4, 1] + (0.5 if r1[3, 4, 1] < 0.5 else -0.5)
    assert im.flicker(r0, t1, r0, r1) == pytest.approx(0.5 / 360)
    a = _img(7)
    assert im.flicker(a, a, a, a) == 0.0
    with pytest.raises(ValueError, match="shapes differ"):
        im.flicker(a, a, _img(shape=(4, 4, 3)), _img(shape=(4, 4, 3)))


def test_report_flicker_from_consecutive_frame_pairs(write_scene, tmp_path):
    from crowd.images import read_png

    scene = write_scene(REPORT_SCENE.replace("frames = 6", "frames = 7"))
    out = tmp_path / "rep"
    r = run_cli("report", scene, "--sweep", "lod.mode=none,points", "--out", out, "--sample-every", "3",
                "--cluster", "none", "--quiet")
    assert r.returncode == 0, r.stderr
    data = json.loads((out / "report.json").read_text())
    (sc,) = data["scenes"]
    nolod, pts = sc["settings"]
    # pairs (0, 1), (3, 4) and frame 6 without a successor in a 7-frame run; frames 2 and 5 are not written
    for s in ("s0", "s1"):
        frames = sorted(p.name for p in (out / "runs" / sc["slug"] / s / "frames").iterdir())
        assert frames == [f"frame_{f:05d}.png" for f in (0, 1, 3, 4, 6)]
    assert [m["frame"] for m in pts["samples"]] == [0, 3, 6]
    assert [m["flicker"] is None for m in pts["samples"]] == [False, False, True]
    assert all(m["aliased"]["flicker"] == 0.0 for m in nolod["samples"][:2])
    assert nolod["accuracy_aliased"]["flicker"] == 0.0
    d = out / "runs" / sc["slug"]
    png = lambda s, f: read_png(d / s / "frames" / f"frame_{f:05d}.png")  # noqa: E731
    # flicker against the reference's own change between frames (the supersampled reference's pair)
    ref = "reference_96x72"
    assert sorted(p.name for p in (d / ref / "frames").iterdir()) == [f"frame_{f:05d}.png" for f in (0, 1, 3, 4, 6)]
    want = im.flicker(png("s1", 3), png("s1", 4), png(ref, 3), png(ref, 4))
    assert pts["samples"][1]["flicker"] == pytest.approx(want) and math.isfinite(want) and want >= 0.0
    want = im.flicker(png("s1", 3), png("s1", 4), png("s0", 3), png("s0", 4))
    assert pts["samples"][1]["aliased"]["flicker"] == pytest.approx(want)
    assert pts["accuracy"]["flicker"] == pytest.approx(np.mean([m["flicker"] for m in pts["samples"][:2]]))
    page = (out / "index.html").read_text()
    assert "LOD flicker" in page and (out / sc["plots"]["flicker"]).is_file()


# ------------------------------------------------------------------------------------------------ dask.distributed
def _strip_times(entry):
    """A setting entry without what depends on wall-clock time or the machine that ran it."""
    return {k: v for k, v in entry.items() if k not in ("frame_ms", "stage_ms", "gpu_ms", "repeat_medians_ms",
                                                         "host")}


def test_sweep_through_a_local_dask_cluster_matches_the_local_path(write_scene, tmp_path, dask_cluster):
    from crowd.images import read_png

    addr = dask_cluster
    assert addr.startswith("tcp://127.0.0.1:")
    scene = write_scene(REPORT_SCENE.replace("frames = 6", "frames = 3"))
    args = ("report", scene, "--sweep", "lod.mode=none,points", "--sample-every", "2", "--quiet")
    r = run_cli(*args, "--out", tmp_path / "dask", "--cluster", addr)
    assert r.returncode == 0, r.stderr
    r = run_cli(*args, "--out", tmp_path / "here", "--cluster", "none")
    assert r.returncode == 0, r.stderr
    dd, hd = (json.loads((tmp_path / d / "report.json").read_text()) for d in ("dask", "here"))
    assert dd["cluster"] == f"dask scheduler {addr}" and dd["hosts"] == {"127.0.0.1": 2}
    assert hd["cluster"] == "this process"
    (ds,), (hs,) = dd["scenes"], hd["scenes"]
    assert [s["label"] for s in ds["settings"]] == [s["label"] for s in hs["settings"]] == [
        "lod.mode=none", "lod.mode=points"]
    for a, b in zip(ds["settings"], hs["settings"]):
        assert a["triangles"] == b["triangles"] and a["points"] == b["points"] and a["instances"] == b["instances"]
        assert [m["frame"] for m in a["samples"]] == [m["frame"] for m in b["samples"]] == [0, 2]
        for ma, mb in zip(a["samples"], b["samples"]):
            for k in ("psnr", "ssim", "flip", "mse", "flicker"):
                assert (ma[k] is None and mb[k] is None) or ma[k] == pytest.approx(mb[k], rel=1e-9, abs=1e-12), k
            assert np.array_equal(read_png(tmp_path / "dask" / ma["error"]), read_png(tmp_path / "here" / mb["error"]))
        assert _strip_times(a)["accuracy"] == pytest.approx(_strip_times(b)["accuracy"])
    assert ds["settings"][1]["points"] > 0 and not ds["settings"][1]["accuracy"]["identical"]
    assert ds["settings"][1]["samples"][0]["flicker"] is not None  # the pair (0, 1) came back from the workers
    # the schedule: timed runs never overlap on the host; nothing else started before the last one ended
    sched = dd["schedule"]
    timed = sorted((x["start"], x["end"]) for x in sched if x["kind"] == "timed")
    assert len(timed) == 2 and all(a[1] <= b[0] for a, b in zip(timed, timed[1:]))
    refs = [x for x in sched if x["kind"] == "reference"]  # the true reference, after every timed run
    assert len(refs) == 1 and refs[0]["start"] >= max(t[1] for t in timed)
    # the second report (this process) found the first's reference frames in the cache
    assert [r["cached"] for r in hd["scenes"][0]["reference"]] == [3]
    # the pages of both paths name the same images
    pages = [(tmp_path / d / "index.html").read_text() for d in ("dask", "here")]
    assert re.findall(r"<img src='([^']+)'", pages[0]) == re.findall(r"<img src='([^']+)'", pages[1])
    assert "one at a time per host" in pages[0]


def test_reference_runs_follow_the_timed_runs_on_the_cluster(write_scene, tmp_path, dask_cluster):
    scene = write_scene(REPORT_SCENE.replace("frames = 6", "frames = 2"))
    out = tmp_path / "rep"
    r = run_cli("report", scene, "--sweep", "lod.mode=clusters,points", "--out", out, "--cluster", dask_cluster,
                "--repeat", "2", "--quiet")
    assert r.returncode == 0, r.stderr
    data = json.loads((out / "report.json").read_text())
    sched = data["schedule"]
    timed = sorted((x["start"], x["end"]) for x in sched if x["kind"] == "timed")
    refs = [x for x in sched if x["kind"] == "reference"]
    assert len(timed) == 6 and len(refs) == 1 and refs[0]["label"] == "96x72"  # aliased full detail timed too
    assert all(a[1] <= b[0] for a, b in zip(timed, timed[1:]))
    assert refs[0]["start"] >= timed[-1][1]
    assert all(len(s["repeat_medians_ms"]) == 2 for s in data["scenes"][0]["settings"])
    assert (out / "runs" / "tiny" / "reference_96x72" / "frames" / "frame_00000.png").is_file()
    assert sorted(p.name for p in (out / "runs" / "tiny").iterdir()) == ["reference_96x72", "s0", "s0_r1", "s1",
                                                                          "s1_r1", "s2", "s2_r1"]


def test_metrics_pool_map_on_the_cluster_equals_this_process(dask_cluster):
    from crowd.report.cluster import ClusterPool
    from crowd.report.metrics import frame_metrics

    rng = np.random.default_rng(9)
    args = [tuple(rng.integers(0, 256, (20, 24, 3), dtype=np.uint8) for _ in range(4)),
            (_img(1, (20, 24, 3)), _img(2, (20, 24, 3)), None, None)]
    with ClusterPool(dask_cluster) as pool:
        assert pool.distributed and pool.hosts() == {"127.0.0.1": sorted(pool.hosts()["127.0.0.1"])}
        remote = pool.map(frame_metrics, args)
    for a, rm in zip(args, remote):
        lm = frame_metrics(*a)
        assert np.array_equal(lm.pop("error_png"), rm.pop("error_png")) and lm == rm


def test_cluster_argument_errors(write_scene, tmp_path):
    from crowd.report.cluster import ClusterPool

    with ClusterPool("none") as pool:
        assert not pool.distributed and pool.description == "this process" and pool.submit(max, 1, 2).result() == 2
    with pytest.raises(CrowdError, match="expected 'local'"):
        ClusterPool("somewhere")
    from crowd.report.cluster import shutdown_dask

    class Slow:  # a cluster whose workers take longer to exit than distributed waits
        closed = 0

        def close(self):
            Slow.closed += 1
            raise TimeoutError

    shutdown_dask(Slow(), Slow())  # the work is complete: a slow shutdown is no error
    assert Slow.closed == 2
    scene = write_scene(REPORT_SCENE)
    r = run_cli("report", scene, "--out", tmp_path / "o", "--cluster", "localhost:8786")
    assert r.returncode == 2 and "tcp://HOST:PORT" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "o").exists()


def test_sweep_of_a_key_every_mode_takes(write_scene):
    """``lod.keyframe_every`` (lod.temporal.selection: a key of every mode) is swept across modes and kept when
    lod.mode is swept; a NoLOD setting with keyframing is not its own reference, nor one sharing quantised poses
    (``pose_rate`` at its default, lod.poses): the reference draws exact times; ``pose_rate = 0`` is one."""
    ks = pytest.importorskip("lod.temporal.selection", reason="keyframed selection is not in this tree")
    from crowd.reference import is_reference as _is_reference, reference_scene as _reference_scene

    assert "keyframe_every" in ks.LOD_COMMON_PARAMS
    p = write_scene(REPORT_SCENE)
    sets = expand_settings(p, [parse_sweep("lod.mode=none,clusters"), parse_sweep("lod.keyframe_every=1,4")])
    assert [s.label for s in sets] == ["lod.mode=none, lod.keyframe_every=1", "lod.mode=none, lod.keyframe_every=4",
                                       "lod.mode=clusters, lod.keyframe_every=1",
                                       "lod.mode=clusters, lod.keyframe_every=4"]
    assert [dict(s.scene.lod_common)["keyframe_every"] for s in sets] == [1, 4, 1, 4]
    assert [_is_reference(s.scene) for s in sets] == [True, False, False, False]
    assert all(_is_reference(_reference_scene(s.scene)) for s in sets)
    assert dict(_reference_scene(sets[1].scene).lod_common) == {"pose_rate": 0.0}
    sets = expand_settings(p, [parse_sweep("lod.pose_rate=0,key,10")])
    assert [s.label for s in sets] == ["lod.pose_rate=0", "lod.pose_rate=key", "lod.pose_rate=10"]
    assert [_is_reference(s.scene) for s in sets] == [True, False, False]


def test_a_run_that_fails_on_bad_input_is_one_sentence_exit_2(write_scene, tmp_path):
    """An error only the run finds (an unknown clip, found when the engine builds the placement) comes back from
    the task as one sentence: exit code 2, nothing written."""
    from crowd.report.runs import _checked, run_task

    scene = write_scene(REPORT_SCENE.replace('character = "walker"', 'character = "walker"\nclip = "nope"'))
    out = tmp_path / "rep"
    r = run_cli("report", scene, "--out", out, "--cluster", "none")
    lines = [x for x in r.stderr.strip().splitlines() if not x.startswith("report [")]  # progress before it
    assert r.returncode == 2 and len(lines) == 1 and "clip" in lines[0] and "'nope'" in lines[0], r.stderr
    assert r.stderr.strip().splitlines()[-1] == lines[0]  # the error is the last word
    assert "Traceback" not in r.stderr and not out.exists() and not list(tmp_path.glob(".rep*"))
    err = {"error": "x.toml: frame 3: NaN in positions", "exit_code": 3}
    with pytest.raises(CrowdError, match="NaN") as e:
        _checked(err)
    assert e.value.exit_code == 3
    assert run_task.__doc__ and _checked({"a": 1}) == {"a": 1}


def test_report_progress_without_a_terminal_is_one_line_per_step(write_scene, tmp_path):
    """stderr a pipe (a log, CI): the plan first (before any run), then one line per timed run and reference."""
    scene = write_scene(REPORT_SCENE.replace("frames = 6", "frames = 2"))
    out = tmp_path / "rep"
    r = run_cli("report", scene, "--sweep", "lod.mode=none,points,clusters,triangles", "--out", out,
                "--cluster", "none")
    assert r.returncode == 0, r.stderr
    lines = [x for x in r.stderr.splitlines() if x.startswith("report [")]
    assert lines[0].endswith("1 scene(s), 4 setting(s): 4 timed run(s), 1 reference(s) at K = 4, 16 image "
                             "comparisons; starting in this process")
    timed = [x for x in lines if "timed run of tiny [" in x]
    assert [x.split("[", 2)[2].split("]")[0] for x in timed] == [
        "lod.mode=none", "lod.mode=points", "lod.mode=clusters", "lod.mode=triangles"]
    assert any("reference of tiny 96x72: 2 frames" in x for x in lines)
    assert (out / "table.md").is_file() and (out / "table.csv").is_file()
    q = run_cli("report", scene, "--out", tmp_path / "q", "--cluster", "none", "--quiet")
    assert q.returncode == 0 and q.stderr.strip() == "" and q.stdout.strip() == ""
