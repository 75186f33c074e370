"""``crowd report --compare``: frame-time regressions against a baseline report beyond run-to-run noise."""
import json
import math

import pytest
from crowd_testutil import run_cli, tiny_scene

from crowd.errors import CrowdError
from crowd.report.compare import MIN_REGRESSION, NOISE_K, compare_reports, load_baseline
from crowd.report.runs import SLEEP_ENV, test_sleep_seconds

SCENE = tiny_scene(replace={"frames = 3": "frames = 4", "png_every = 1": "png_every = 0"})


def _report(medians_by_label, name="tiny"):
    return {"scenes": [{"name": name, "settings": [{"label": k, "repeat_medians_ms": v, "frame_ms": {"p50": v[0]}}
                                                   for k, v in medians_by_label.items()]}]}


def test_compare_against_itself_has_no_regression():
    rep = _report({"lod.mode=none": [10.0, 10.4, 9.9], "lod.mode=clusters": [5.0, 5.0, 5.0]})
    rows = compare_reports(rep, rep)
    assert [r["label"] for r in rows] == ["lod.mode=none", "lod.mode=clusters"]
    assert all(r["ratio"] == 1.0 and not r["regression"] for r in rows)
    # threshold: max(5 %, 3 x 1.4826 MAD / median); MAD of (10.0, 10.4, 9.9) is 0.1 around 10.0
    assert rows[0]["spread_current"] == pytest.approx(1.4826 * 0.1 / 10.0)
    assert rows[0]["threshold"] == pytest.approx(max(MIN_REGRESSION, NOISE_K * 1.4826 * 0.01))
    assert rows[1]["threshold"] == MIN_REGRESSION and rows[1]["spread_current"] == 0.0


def test_threshold_follows_the_measured_spread():
    base = _report({"a": [10.0, 10.0, 10.0], "b": [10.0, 10.0, 10.0], "c": [10.0, 8.0, 12.0]})
    cur = _report({"a": [10.3, 10.4, 10.5], "b": [10.7, 10.6, 10.6], "c": [13.0, 13.5, 14.0]})
    r = {x["label"]: x for x in compare_reports(cur, base)}
    assert r["a"]["ratio"] == pytest.approx(1.04) and not r["a"]["regression"]  # within 5 %
    assert r["b"]["ratio"] == pytest.approx(1.06) and r["b"]["regression"]      # beyond 5 %, spreads tiny
    # c: baseline spread 1.4826 * 2 / 10 = 29.7 % -> threshold 89 %: a 35 % slowdown is noise
    assert r["c"]["threshold"] == pytest.approx(3 * 1.4826 * 0.2) and not r["c"]["regression"]
    # one slow run of three does not widen the threshold (MAD), unlike a max/min range would
    r = compare_reports(_report({"d": [10.0, 10.0, 10.0]}), _report({"d": [25.0, 10.0, 10.0]}))[0]
    assert r["spread_baseline"] == 0.0 and r["threshold"] == MIN_REGRESSION


def test_compare_matches_by_scene_and_label_and_reads_old_reports():
    base = {"scenes": [{"name": "tiny", "settings": [{"label": "x", "frame_ms": {"p50": 4.0}}]},
                       {"name": "other", "settings": [{"label": "y", "frame_ms": {"p50": 1.0}}]}]}
    cur = _report({"x": [8.0, 8.0, 8.0], "z": [1.0]})
    (row,) = compare_reports(cur, base)  # no baseline for z; scene 'other' not in the current report
    assert row["label"] == "x" and row["ratio"] == 2.0 and row["runs_baseline"] == 1 and row["regression"]


def test_bad_baseline_and_sleep_setting(tmp_path, monkeypatch):
    with pytest.raises(CrowdError, match="report.json"):
        load_baseline(tmp_path)
    (tmp_path / "report.json").write_text("[]")
    with pytest.raises(CrowdError, match="not a crowd report"):
        load_baseline(tmp_path)
    monkeypatch.setenv(SLEEP_ENV, "abc")
    with pytest.raises(CrowdError, match=SLEEP_ENV):
        test_sleep_seconds()
    monkeypatch.setenv(SLEEP_ENV, "25")
    assert test_sleep_seconds() == pytest.approx(0.025)
    monkeypatch.delenv(SLEEP_ENV)
    assert test_sleep_seconds() == 0.0


def test_compare_cli_flags_an_artificially_slower_run(write_scene, tmp_path, monkeypatch):
    scene = write_scene(SCENE)
    base, slow, fast = tmp_path / "base", tmp_path / "slow", tmp_path / "fast"
    monkeypatch.delenv(SLEEP_ENV, raising=False)
    r = run_cli("report", scene, "--out", base, "--repeat", "3", "--quiet")  # the default: an embedded LocalCluster
    assert r.returncode == 0, r.stderr
    b = json.loads((base / "report.json").read_text())
    assert b["cluster"].startswith("embedded dask LocalCluster tcp://127.0.0.1:")
    st, aliased = b["scenes"][0]["settings"]  # the scene, and aliased full detail (its mode none is not exact)
    assert aliased["label"] == "full detail (aliased)" and len(aliased["repeat_medians_ms"]) == 3
    assert len(st["repeat_medians_ms"]) == 3 and all(m > 0 for m in st["repeat_medians_ms"])
    assert "compare" not in b

    monkeypatch.setenv(SLEEP_ENV, "60")  # 60 ms inside every timed frame
    r = run_cli("report", scene, "--out", slow, "--compare", base, "--cluster", "none", "--quiet")
    assert r.returncode == 1, r.stderr
    # the sleep is in every timed run: the scene's and aliased full detail's
    assert "REGRESSION tiny [scene]" in r.stdout and "REGRESSION tiny [full detail (aliased)]" in r.stdout
    assert "2 regression(s)" in r.stdout
    s = json.loads((slow / "report.json").read_text())
    assert s["repeat"] == 3 and s["compare"]["regressions"] == 2
    for row in s["compare"]["rows"]:
        assert row["regression"] and row["current_ms"] >= 60.0 and row["ratio"] > 1 + row["threshold"]
    page = (slow / "index.html").read_text()
    assert "Comparison with baseline" in page and "<tr class='regressed'>" in page

    monkeypatch.delenv(SLEEP_ENV)  # the slow run as baseline: the normal run is no regression
    r = run_cli("report", scene, "--out", fast, "--compare", slow, "--repeat", "2", "--cluster", "none", "--quiet")
    assert r.returncode == 0, r.stdout + r.stderr
    f = json.loads((fast / "report.json").read_text())
    assert len(f["compare"]["rows"]) == 2
    for row in f["compare"]["rows"]:
        assert not row["regression"] and row["ratio"] < 1.0 and row["runs_current"] == 2
    assert "REGRESSION" not in r.stdout and "0 regression(s)" in (fast / "index.html").read_text()


def test_compare_with_a_missing_baseline_is_exit_2(write_scene, tmp_path):
    scene = write_scene(SCENE)
    r = run_cli("report", scene, "--out", tmp_path / "o", "--compare", tmp_path / "nope", "--cluster", "none",
                "--quiet")
    assert r.returncode == 2 and "report.json" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "o").exists()
