"""crowd.telemetry: frames.csv columns, summary statistics, Chrome trace structure."""
import csv
import json

import numpy as np
import pytest

from crowd.telemetry import COUNTS, STAGES, FrameRecord, Telemetry, machine_info, stats


def _telemetry(n=5, gpu=True):
    tel = Telemetry(systems=["animation"])
    t = 0.0
    for f in range(n):
        stages, off = {}, 0.0
        for i, s in enumerate(STAGES):
            d = 0.001 * (i + 1) * (f + 1)
            stages[s] = (off, d)
            off += d
        tel.add(FrameRecord(frame=f, sim_time=(f + 1) / 30, start=t, total=off + 0.0005, stages=stages,
                            gpu=0.002 * (f + 1) if gpu else None,
                            systems={"animation": 0.0004, "boids": 0.0003} if f else {"animation": 0.0004},
                            counts={"instances": 4, "culled": 1, "triangles": 4000 + f, "points": 0, "batches": 1},
                            samples_passed=100))
        t += off + 0.001
    return tel


def test_stats_percentiles():
    s = stats(np.arange(101, dtype=float))
    assert s == {"mean": 50.0, "p50": 50.0, "p95": 95.0, "p99": 99.0, "max": 100.0}
    assert stats([])["max"] == 0.0


def test_frames_csv_columns_and_values(tmp_path):
    tel = _telemetry()
    tel.write(tmp_path, "tiny", machine={"cpu": "test"})
    rows = list(csv.DictReader((tmp_path / "frames.csv").open()))
    assert list(rows[0]) == (["frame", "sim_time", "total", *STAGES, "gpu", "sys.animation", "sys.boids",
                              *COUNTS, "samples_passed"])
    assert len(rows) == 5
    assert rows[0]["sys.boids"] == "0" and float(rows[1]["sys.boids"]) == pytest.approx(0.0003)
    assert [int(r["triangles"]) for r in rows] == [4000, 4001, 4002, 4003, 4004]
    assert float(rows[2]["draw"]) == pytest.approx(0.012)


def test_gpu_column_blank_when_unavailable(tmp_path):
    tel = _telemetry(gpu=False)
    summary = tel.write(tmp_path, "tiny", machine={})
    rows = list(csv.DictReader((tmp_path / "frames.csv").open()))
    assert all(r["gpu"] == "" for r in rows)
    assert summary["stages"]["gpu"] is None


def test_summary_json(tmp_path):
    _telemetry().write(tmp_path, "tiny", extra={"agents": 4}, machine={"cpu": "test"})
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["scene"] == "tiny" and s["frames"] == 5 and s["agents"] == 4
    for stage in (*STAGES, "total", "gpu"):
        assert set(s["stages"][stage]) == {"mean", "p50", "p95", "p99", "max"}
    assert s["stages"]["simulate"]["max"] == pytest.approx(0.005)
    assert set(s["systems"]) == {"animation", "boids"}
    assert s["counts"]["triangles"] == {"total": 20010, "mean": 4002.0, "max": 4004}


def test_trace_is_valid_chrome_trace_event_json(tmp_path):
    tel = _telemetry()
    tel.write(tmp_path, "tiny", machine={})
    trace = json.loads((tmp_path / "trace.json").read_text())
    ev = trace["traceEvents"]
    assert isinstance(ev, list) and ev
    for e in ev:
        assert e["ph"] in ("X", "C", "M")
        assert isinstance(e["name"], str) and isinstance(e["pid"], int)
        if e["ph"] == "X":
            assert isinstance(e["tid"], int) and e["ts"] >= 0 and e["dur"] >= 0
        if e["ph"] == "C":
            assert e["ts"] >= 0 and all(isinstance(v, (int, float)) for v in e["args"].values())
    stages = [e for e in ev if e["ph"] == "X" and e.get("cat") == "stage"]
    assert len(stages) == 5 * len(STAGES)
    frames = {e["args"]["frame"]: e for e in ev if e["ph"] == "X" and e.get("cat") == "frame"}
    for e in stages + [e for e in ev if e.get("cat") in ("system", "gpu")]:
        fr = frames[e["args"]["frame"]]
        assert fr["ts"] - 1e-6 <= e["ts"]  # inside (or at) its frame's start
    # stages on one track do not overlap
    for f in frames:
        sp = sorted((e["ts"], e["ts"] + e["dur"]) for e in stages if e["args"]["frame"] == f)
        assert all(a[1] <= b[0] + 1e-6 for a, b in zip(sp, sp[1:]))
    counters = {e["name"] for e in ev if e["ph"] == "C"}
    assert {"triangles", "instances"} <= counters


def test_machine_info_fields():
    m = machine_info({"GL_RENDERER": "llvmpipe", "GL_VERSION": "4.5"})
    assert m["gl_renderer"] == "llvmpipe" and m["cores"] >= 1 and m["cpu"]
    assert m["packages"]["numpy"]
