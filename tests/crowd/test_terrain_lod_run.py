"""The view-dependent bisection terrain (Friedrich et al.) in a real run: the
[terrain] table's LOD keys are validated, the terrain is re-selected every n-th
frame and interpolated in between, and its figures reach frames.csv."""
import csv
import json

from crowd_testutil import run_cli, tiny_scene

TERRAIN = """
[terrain]
size = [64.0, 64.0]
origin = [-32.0, 0.0, -32.0]
resolution = 65
height_scale = 4.0
seed = 3
"""


def _scene(tmp_path, extra):
    p = tmp_path / "t.toml"
    text = tiny_scene(replace={"frames = 3": "frames = 10", "size = [64, 48]": "size = [160, 120]",
                               "png_every = 1": "png_every = 0",
                               "position = [1.0, 2.0, 7.0]": "position = [1.0, 12.0, 30.0]"})
    p.write_text(text + TERRAIN + extra)
    return p


def test_bisection_terrain_runs_and_logs_its_error_terms(tmp_path):
    scene = _scene(tmp_path, 'lod = "bisection"\nlod_keyframe_every = 4\nlod_measure_errors = true\n')
    out = tmp_path / "out"
    r = run_cli("run", scene, "--out", out, "--quiet")
    assert r.returncode == 0, r.stderr
    rows = list(csv.DictReader(open(out / "frames.csv")))
    assert len(rows) == 10
    tris = [float(row["terrain_triangles"]) for row in rows]
    full = 2 * 64 * 64
    assert all(0 < t < full for t in tris)
    selected = [float(row["terrain_selected"]) for row in rows]
    assert 2 <= sum(selected) <= 4  # a selection every 4th frame, not every frame
    for k in ("err_inter", "err_view", "err_extra"):
        v = [float(row[k]) for row in rows]
        assert all(x >= 0.0 and x == x for x in v)
    summary = json.loads((out / "summary.json").read_text())
    assert "terrain_triangles" in summary["metrics"]


def test_full_resolution_terrain_has_no_lod_columns_and_bad_lod_key_is_refused(tmp_path):
    out = tmp_path / "out"
    r = run_cli("run", _scene(tmp_path, ""), "--out", out, "--quiet")
    assert r.returncode == 0, r.stderr
    header = open(out / "frames.csv").readline()
    assert "err_inter" not in header
    bad = _scene(tmp_path, 'lod = "quadtree"\n')
    r = run_cli("validate", bad)
    assert r.returncode == 2 and "terrain.lod" in r.stderr and "bisection" in r.stderr
    bad = _scene(tmp_path, 'lod_taux = 2.0\n')
    r = run_cli("validate", bad)
    assert r.returncode == 2 and "terrain.lod_taux" in r.stderr and "lod_tau" in r.stderr
