"""lod/auto/cost_model.py: NNLS fit, prediction from draw lists, per-machine storage, defaults."""
import json

import numpy as np
import pytest

from lod.auto import cost_model as cm
from lod.drawlist import DrawBatch, DrawList

TRUE = {"frame": 2e-3, "triangles": 1.3e-7, "points": 4e-8, "batches": 6e-5, "instances": 2e-6, "clusters": 3e-7,
        "splat_pixels": 2e-8, "splat_area": 3e-9, "point_instances": 5e-6, "cluster_frames": 4e-3}


def _samples(n=40, seed=0):
    rng = np.random.default_rng(seed)
    px = rng.choice([0.0, 1280 * 720, 640 * 360], n)
    X = np.stack([rng.integers(0, 2_000_000, n), rng.integers(0, 5_000_000, n), rng.integers(1, 200, n),
                  rng.integers(1, 5000, n), rng.integers(0, 20000, n), px,
                  px * rng.choice([1.0, 4.0, 9.0], n), rng.integers(0, 3000, n), rng.integers(0, 2, n)],
                 axis=1).astype(float)
    y = cm.CostModel(TRUE).predict_counts(*X.T)
    return X, y


def _dl(tri=(1000,), inst=(3,), points=0, clusters=None):
    bs = [DrawBatch("none:a", 0, np.arange(k, dtype=np.int32), np.zeros((k, 16), np.float32), triangles=t)
          for t, k in zip(tri, inst)]
    if points:
        bs.append(DrawBatch("points:a", 0, np.zeros(1, np.int32), np.zeros((1, 16), np.float32), points=points))
    st = {} if clusters is None else {"clusters": clusters}
    return DrawList(np.zeros(3), np.eye(4), np.eye(4), (64, 48), batches=bs, stats=st)


def test_fit_recovers_known_coefficients_exactly():
    X, y = _samples()
    coef, err = cm.fit(X, y)
    np.testing.assert_allclose(coef, [TRUE[k] for k in cm.COEFFICIENTS], rtol=1e-6)
    assert err < 1e-9
    m = cm.fit_model(X, y, key="k")
    assert m.samples == 40 and m.median_rel_error < 1e-9
    for k in cm.COEFFICIENTS:
        assert m.coefficients[k] == pytest.approx(TRUE[k], rel=1e-6)


def test_fit_is_non_negative_and_unused_features_keep_defaults():
    X, y = _samples()
    X[:, 1] = 0.0  # points never measured
    y = y - 0.5 * y.min()  # inconsistent data: unconstrained LSQ would go negative somewhere
    m = cm.fit_model(X, y, key="k")
    assert all(v >= 0 for v in m.coefficients.values())
    assert m.coefficients["points"] == cm.DEFAULTS["points"]


def test_fit_rejects_degenerate_input():
    with pytest.raises(ValueError, match="non-empty"):
        cm.fit(np.zeros((0, 9)), np.zeros(0))
    with pytest.raises(ValueError, match="finite"):
        cm.fit(np.ones((2, 9)), np.array([1.0, np.nan]))
    with pytest.raises(ValueError, match="finite"):
        cm.fit(np.ones((2, 9)), np.array([1.0, 0.0]))
    with pytest.raises(ValueError, match="non-empty"):
        cm.relative_error(cm.CostModel(), np.ones((1, 9)), np.array([0.0]))
    with pytest.raises(ValueError, match="unknown coefficient"):
        cm.CostModel({"bogus": 1.0})
    with pytest.raises(ValueError, match=">= 0"):
        cm.CostModel({"triangles": -1.0})


def test_features_and_predict_from_drawlist():
    m = cm.CostModel(TRUE)
    dl = _dl(tri=(1000, 500), inst=(3, 2), points=700, clusters=11)
    dl.options["splat_size"] = 3
    np.testing.assert_array_equal(cm.features(dl), [1500, 700, 3, 6, 11, 64 * 48, 64 * 48 * 9, 0, 0])
    want = TRUE["frame"] + 1500 * TRUE["triangles"] + 700 * TRUE["points"] + 3 * TRUE["batches"] + \
        6 * TRUE["instances"] + 11 * TRUE["clusters"] + 64 * 48 * (TRUE["splat_pixels"] + 9 * TRUE["splat_area"])
    assert m.predict(dl) == pytest.approx(want, rel=1e-12)
    assert cm.pass_cost(m, (64, 48), 3) == pytest.approx(64 * 48 * (TRUE["splat_pixels"] + 9 * TRUE["splat_area"]))
    nopts = _dl(tri=(1000,), inst=(3,))
    assert cm.features(nopts)[5:].tolist() == [0.0, 0.0, 0.0, 0.0]  # no points: no splat pass
    pb = DrawBatch("points:a", 0, np.arange(4, dtype=np.int32), np.zeros((4, 16), np.float32), points=9)
    pb.point_jobs = np.zeros((0, 3), np.int64)  # a PointsBatch: its instances are point instances
    f = cm.features(DrawList(np.zeros(3), np.eye(4), np.eye(4), (8, 8), batches=[pb, *nopts.batches]))
    assert f[7] == 4 and f[3] == 3 and f[8] == 0  # instances: the triangle paths' only
    cb = DrawBatch("clusters:a", 0, np.arange(2, dtype=np.int32), np.zeros((2, 16), np.float32), triangles=5)
    cb.offsets = np.array([0, 1, 2])
    assert cm.features(DrawList(np.zeros(3), np.eye(4), np.eye(4), (8, 8), batches=[cb]))[8] == 1
    X = np.stack([cm.features(dl), cm.features(nopts)])
    y = np.array([m.predict(dl), 2 * m.predict(nopts)])
    assert cm.relative_error(m, X, y) == pytest.approx(0.25)  # errors 0 and 0.5
    empty = DrawList(np.zeros(3), np.eye(4), np.eye(4), (64, 48))
    assert m.predict(empty) == pytest.approx(TRUE["frame"])


def test_predict_is_monotone_in_every_count():
    m = cm.CostModel()
    base = m.predict(_dl())
    assert m.predict(_dl(tri=(2000,))) > base
    assert m.predict(_dl(inst=(5,))) > base
    assert m.predict(_dl(tri=(500, 500), inst=(1, 2))) > base  # one more batch, same work
    assert m.predict(_dl(points=10)) > base
    assert m.predict(_dl(clusters=10)) > base
    c = np.linspace(0, 1e7, 50)
    assert np.all(np.diff(m.predict_counts(triangles=c)) > 0)


def test_save_load_round_trip_keeps_other_machines(tmp_path):
    X, y = _samples()
    m = cm.fit_model(X, y, key=cm.machine_key("llvmpipe (test)"))
    p = cm.save(m, tmp_path)
    other = cm.CostModel(TRUE, key="elsewhere|x86_64|GPU")
    cm.save(other, tmp_path)
    assert not list(tmp_path.glob("*.tmp"))
    back = cm.load("llvmpipe (test)", directory=tmp_path)
    assert back.key == m.key and back.samples == 40
    np.testing.assert_allclose(back.vector, m.vector, rtol=1e-12)
    assert back.median_rel_error == pytest.approx(m.median_rel_error)
    assert set(json.loads(p.read_text())["machines"]) == {m.key, other.key}
    assert cm.load_any(tmp_path).key == m.key
    with pytest.raises(ValueError, match="machine key"):
        cm.save(cm.CostModel(), tmp_path)


def test_unknown_machine_or_damaged_file_falls_back_to_defaults(tmp_path, monkeypatch):
    d = cm.load("some other GPU", directory=tmp_path)
    assert d.is_default and d.coefficients == cm.DEFAULTS
    (tmp_path / cm.FILE_NAME).write_text("{not json")
    assert cm.load("x", directory=tmp_path).is_default
    (tmp_path / cm.FILE_NAME).write_text(json.dumps({"format": 1, "machines": {cm.machine_key("x"): {
        "coefficients": {"triangles": "NaN"}}}}))
    assert cm.load("x", directory=tmp_path).is_default
    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path / "c"))
    assert cm.cache_dir() == tmp_path / "c"
    assert cm.load_any().is_default
    assert cm.DEFAULTS["triangles"] == pytest.approx(1 / 8e6) and cm.DEFAULTS["points"] == pytest.approx(1 / 27e6)


def test_crowd_calibrate_quick_stores_a_model(tmp_path):
    """`crowd calibrate --quick` (crowd/calibrate.py) measures headless full-detail, cluster and point
    draw lists (12 + 4 + 4 + 3 frames), fits and stores this machine's model, with its error on held-out
    mixed lists of mode auto."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[3]
    env = dict(os.environ, CROWD_CACHE_DIR=str(tmp_path))
    env["PYTHONPATH"] = str(repo) + os.pathsep + env.get("PYTHONPATH", "")
    p = subprocess.run([sys.executable, "-m", "crowd", "calibrate", "--quick", "--size", "320x240"],
                       capture_output=True, text=True, cwd=repo, env=env, timeout=300)
    assert p.returncode == 0, p.stderr
    assert "fit median relative error" in p.stdout and "per triangle" in p.stdout and "held out" in p.stdout
    m = cm.load_any(tmp_path)
    assert not m.is_default and m.samples == 23 and "llvmpipe" in m.key.lower()
    assert np.isfinite(m.vector).all() and (m.vector >= 0).all() and m.median_rel_error is not None
    assert m.validation_rel_error is not None and np.isfinite(m.validation_rel_error)
    assert m.coefficients["triangles"] > 0 or m.coefficients["instances"] > 0
    q = subprocess.run([sys.executable, "-m", "crowd", "calibrate", "--quick", "--size", "0x0"],
                       capture_output=True, text=True, cwd=repo, env=env, timeout=60)
    assert q.returncode == 2 and "--size" in q.stderr


def test_refine_rescales_the_prior_to_observed_frames():
    """lod.auto.cost_model.refine: a calibration 3x too optimistic, rescaled with frames of the true model,
    predicts them exactly and keeps the relative costs; one wild frame among several does not move
    it (median); no usable frame returns the prior; non-finite rows are ignored."""
    true = cm.CostModel(TRUE)
    prior = cm.CostModel({k: v / 3 for k, v in TRUE.items()}, key="k")
    X, y = _samples(12, seed=5)
    m = cm.refine(prior, X, y)
    assert m.key == "k" and m.samples == 12 and m.median_rel_error < 1e-9
    for k in cm.COEFFICIENTS:
        assert m.coefficients[k] == pytest.approx(true.coefficients[k], rel=1e-9)
    y2 = y.copy()
    y2[0] *= 50.0
    assert cm.relative_error(cm.refine(prior, X, y2), X, y) < 0.05
    assert cm.refine(prior, np.zeros((0, len(cm.FEATURES))), np.zeros(0)) is prior
    bad = np.vstack([X[:2], np.full((1, len(cm.FEATURES)), np.nan)])
    m2 = cm.refine(prior, bad, np.array([y[0], y[1], 1.0]))
    assert m2.samples == 2 and np.isfinite(m2.vector).all() and (m2.vector >= 0).all()


def test_bad_calibration_files_name_the_problem_once(tmp_path, capsys):
    """load/load_any/load_file: a corrupt file, another format, non-finite or negative costs, another machine's
    entries: the defaults and one line on stderr naming the file and the problem (once per process); a
    missing file or entry is silent; unknown coefficient names are ignored (a later version may add some);
    load_file takes a file of one's own (its only entry, whatever machine wrote it)."""
    key = cm.machine_key("x")
    cases = [("{not json", "not valid JSON"), ('{"format": 2, "machines": {}}', "format 2"),
             (json.dumps({"format": 1, "machines": {key: {"coefficients": {"points": float("inf")}}}}), "inf"),
             (json.dumps({"format": 1, "machines": {key: {"coefficients": {"frame": -1.0}}}}), "'frame'"),
             (json.dumps({"format": 1, "machines": {"far|arm|GPU": {"coefficients": {}}}}), "no calibration")]
    for i, (text, what) in enumerate(cases):
        d = tmp_path / str(i)
        d.mkdir()
        (d / cm.FILE_NAME).write_text(text)
        m = cm.load("x", directory=d)
        assert m.is_default and m.coefficients == cm.DEFAULTS
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and str(d / cm.FILE_NAME) in err[0] and what in err[0], err
        cm.load("x", directory=d)
        assert capsys.readouterr().err == ""  # once
    assert cm.load("x", directory=tmp_path / "none").is_default and capsys.readouterr().err == ""
    d = tmp_path / "fwd"
    d.mkdir()
    (d / cm.FILE_NAME).write_text(json.dumps({"format": 1, "machines": {key: {"coefficients": {
        "triangles": 2e-7, "warp_drive": 1.0}}}}))
    m = cm.load("x", directory=d)
    assert m.coefficients["triangles"] == 2e-7 and not m.is_default and capsys.readouterr().err == ""
    other = tmp_path / "mine.json"
    other.write_text(json.dumps({"format": 1, "machines": {"far|arm|GPU": {"coefficients": {"points": 1e-8}}}}))
    m = cm.load_file(other)
    assert m.coefficients["points"] == 1e-8 and m.key == "far|arm|GPU" and capsys.readouterr().err == ""
