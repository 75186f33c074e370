"""lod/cost_model.py: NNLS fit, prediction from draw lists, per-machine storage, defaults."""
import json
from types import SimpleNamespace

import numpy as np
import pytest

from lod import cost_model as cm
from lod.drawlist import DrawBatch, DrawList

TRUE = {"frame": 2e-3, "triangles": 1.3e-7, "points": 4e-8, "batches": 6e-5, "instances": 2e-6, "clusters": 3e-7}


def _samples(n=40, seed=0):
    rng = np.random.default_rng(seed)
    X = np.stack([rng.integers(0, 2_000_000, n), rng.integers(0, 5_000_000, n), rng.integers(1, 200, n),
                  rng.integers(1, 5000, n), rng.integers(0, 20000, n)], axis=1).astype(float)
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
        cm.fit(np.zeros((0, 5)), np.zeros(0))
    with pytest.raises(ValueError, match="finite"):
        cm.fit(np.ones((2, 5)), np.array([1.0, np.nan]))
    with pytest.raises(ValueError, match="finite"):
        cm.fit(np.ones((2, 5)), np.array([1.0, 0.0]))
    with pytest.raises(ValueError, match="unknown coefficient"):
        cm.CostModel({"bogus": 1.0})
    with pytest.raises(ValueError, match=">= 0"):
        cm.CostModel({"triangles": -1.0})


def test_features_and_predict_from_drawlist():
    m = cm.CostModel(TRUE)
    dl = _dl(tri=(1000, 500), inst=(3, 2), points=700, clusters=11)
    np.testing.assert_array_equal(cm.features(dl), [1500, 700, 3, 6, 11])
    want = TRUE["frame"] + 1500 * TRUE["triangles"] + 700 * TRUE["points"] + 3 * TRUE["batches"] + \
        6 * TRUE["instances"] + 11 * TRUE["clusters"]
    assert m.predict(dl) == pytest.approx(want, rel=1e-12)
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
    """`crowd calibrate --quick` (crowd/calibrate.py) measures headless, fits and stores this machine's model."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    env = dict(os.environ, CROWD_CACHE_DIR=str(tmp_path))
    env["PYTHONPATH"] = str(repo) + os.pathsep + env.get("PYTHONPATH", "")
    p = subprocess.run([sys.executable, "-m", "crowd", "calibrate", "--quick", "--size", "320x240"],
                       capture_output=True, text=True, cwd=repo, env=env, timeout=300)
    assert p.returncode == 0, p.stderr
    assert "fit median relative error" in p.stdout and "per triangle" in p.stdout
    m = cm.load_any(tmp_path)
    assert not m.is_default and m.samples == 12 and "llvmpipe" in m.key.lower()
    assert np.isfinite(m.vector).all() and (m.vector >= 0).all() and m.median_rel_error is not None
    assert m.coefficients["points"] == cm.DEFAULTS["points"]  # not measured: default kept
    assert m.coefficients["triangles"] > 0 or m.coefficients["instances"] > 0
    q = subprocess.run([sys.executable, "-m", "crowd", "calibrate", "--quick", "--size", "0x0"],
                       capture_output=True, text=True, cwd=repo, env=env, timeout=60)
    assert q.returncode == 2 and "--size" in q.stderr
