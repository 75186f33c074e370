"""`crowd run --explain-lod` (crowd/explain.py) and unusable calibration files in a run of mode auto: one line,
the run goes on from the neutral prior (lod/auto/cost_model.py)."""
import json

import pytest

from crowd_testutil import run_cli, tiny_scene

AUTO = {'mode = "none"': 'mode = "auto"\npoe = 1.0', "position = [1.0, 2.0, 7.0]": "position = [1.0, 2.0, 30.0]",
        "frames = 3": "frames = 6", "png_every = 1": "png_every = 0"}


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    d = tmp_path_factory.mktemp("explain")
    (d / "tiny.toml").write_text(tiny_scene(replace=AUTO))
    (d / "none.toml").write_text(tiny_scene())
    return d


def test_explain_lod_prints_and_writes_every_frame(scene, tmp_path, monkeypatch):
    """Per frame: the plan and its state, each group's representations, predicted against measured time and the
    online fit's per-unit costs beside the calibration's; the same as JSON records in explain_lod.jsonl."""
    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path / "cache"))
    p = run_cli("run", scene / "tiny.toml", "--out", tmp_path / "out", "--explain-lod")
    assert p.returncode == 0, p.stderr
    assert p.stdout.count("frame ") >= 6 and "predicted" in p.stdout and "per-unit costs" in p.stdout
    assert "ns/triangle" in p.stdout and "walker" in p.stdout
    recs = [json.loads(line) for line in (tmp_path / "out" / "explain_lod.jsonl").read_text().splitlines()]
    assert [r["frame"] for r in recs] == list(range(6))
    for r in recs:
        assert r["plan"] and r["state"] and r["predicted_ms"] > 0 and r["measured_ms"] > 0
        assert sum(sum(g.values()) for g in r["groups"].values()) == 4 or r["state"] == "delegated"
        assert all(k.split("/")[0] == "walker" for k in r["groups"])  # the character, not the master rep's key
        assert r["model"]["coefficients"]["triangles"] > 0 and r["model"]["prior"]["triangles"] > 0
    first = p.stdout.split("frame 1:")[0]  # the neutral prior's scale is free: no ± 100x the mean before a fit
    assert "the prior's guess" in first and "±" not in first.split("predicted")[1].split("\n")[0]
    warm = [r["frame"] for r in recs if r.get("warm_up")]  # draws that made GL objects: not fitted (issue 50)
    assert 0 in warm and "warm-up" in p.stdout
    assert recs[-1]["model"]["frames"] == 5 - len([f for f in warm if f < 5])  # every other frame before the last
    bad = run_cli("run", scene / "none.toml", "--out", tmp_path / "o2", "--explain-lod")
    assert bad.returncode == 2 and "--explain-lod" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o2").exists()


@pytest.mark.parametrize("content, what", [
    ("{not json", "not valid JSON"),
    ('{"format": 7, "machines": {}}', "format 7"),
    ('{"format": 1, "machines": {"otherhost|x86_64|GPU": {"coefficients": {"triangles": 1e-7}}}}',
     "no calibration of this machine"),
    ("NAN", "not valid JSON"),
])
def test_unusable_calibration_file_gives_one_line_and_the_run_goes_on(scene, tmp_path, monkeypatch, content, what):
    """A corrupt file, another format, another machine's file: exit 0, one line naming the file and what is
    wrong, the output written."""
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / "cost_model.json").write_text(content)
    monkeypatch.setenv("CROWD_CACHE_DIR", str(cache))
    p = run_cli("run", scene / "tiny.toml", "--out", tmp_path / "out", "--quiet")
    assert p.returncode == 0, p.stderr
    lines = [x for x in p.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and "cost_model.json" in lines[0] and what in lines[0] and "neutral prior" in lines[0]
    assert (tmp_path / "out" / "frames.csv").is_file()


def test_report_section_on_mode_auto(scene, tmp_path, monkeypatch):
    """`crowd report` of a mode auto setting: its explanation summed up (plans drawn, switches, prediction
    error, fitted per-unit costs) and a plot of predicted against measured frame time."""
    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path / "cache"))
    out = tmp_path / "rep"
    r = run_cli("report", scene / "none.toml", "--sweep", "lod.mode=auto", "--frames", "4", "--out", out,
                "--cluster", "none", "--quiet")
    assert r.returncode == 0, r.stderr
    data = json.loads((out / "report.json").read_text())
    (sc,) = data["scenes"]
    s, aliased = sc["settings"]  # mode auto, and aliased full detail beside it
    assert aliased["auto"] is None and aliased["aliased_full_detail"]
    a = s["auto"]
    assert a["frames"] == 4 and abs(sum(a["plans"].values()) - 1.0) < 1e-9 and a["pred_err"] is not None
    assert a["model"]["coefficients"]["triangles"] > 0
    img = sc["plots"]["auto"][s["slug"]]
    assert (out / img).is_file()
    page = (out / "index.html").read_text()
    assert "Mode auto: what it drew and why" in page and img in page
