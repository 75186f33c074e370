"""``crowd report --sweep render.shadows=none,blob,map``: one setting per shadow mode, timed like LOD settings, each
with its short clip embedded beside its sample frames."""
import json
import re

from crowd_testutil import run_cli, tiny_scene

from crowd.report.settings import expand_settings, parse_sweep
from crowd.video import read_video

SCENE = tiny_scene(replace={"frames = 3": "frames = 4", "png_every = 1": "png_every = 0"})


def test_parse_and_expand_the_shadow_sweep(write_scene):
    assert parse_sweep("render.shadows=none,blob,map") == ("render.shadows", ["none", "blob", "map"])
    assert parse_sweep("render.shadow_map_size=512,1024") == ("render.shadow_map_size", [512, 1024])
    settings = expand_settings(write_scene(SCENE), [parse_sweep("render.shadows=none,map")])
    assert [(s.label, s.scene.render.shadows) for s in settings] == [("render.shadows=none", "none"),
                                                                     ("render.shadows=map", "map")]


def test_report_sweeps_shadows_with_a_clip_per_setting(write_scene, tmp_path):
    out = tmp_path / "rep"
    r = run_cli("report", write_scene(SCENE), "--sweep", "render.shadows=none,blob,map", "--out", out,
                "--sample-every", "2", "--cluster", "none", "--quiet")
    assert r.returncode == 0, r.stderr
    page = (out / "index.html").read_text()
    (sc,) = json.loads((out / "report.json").read_text())["scenes"]
    # each shadow setting against its own reference, beside its own aliased full detail
    assert [s["label"] for s in sc["settings"]] == [f"render.shadows={m}" for m in ("none", "blob", "map")] + [
        f"full detail (aliased), render.shadows={m}" for m in ("none", "blob", "map")]
    assert [(r["label"], r["settings"]) for r in sc["reference"]] == [
        (f"render.shadows={m}", [f"s{i}", f"s{i + 3}"]) for i, m in enumerate(("none", "blob", "map"))]
    clips = re.findall(r"<video src='([^']+)'", page)
    assert clips == [s["clip"] for s in sc["settings"]] and len(set(clips)) == 6
    for s in sc["settings"]:
        assert s["frame_ms"]["p50"] > 0 and f"{s['label']}</td>" in page
        frames, (w, h) = read_video(out / s["clip"])
        assert frames.shape[0] == 4 and (w, h) == (64, 48)
    assert page.index("<h3>Clips</h3>") < page.index("<h3>Sample frames</h3>")


def test_bad_shadow_sweep_value_is_one_line_exit_2(write_scene, tmp_path):
    r = run_cli("report", write_scene(SCENE), "--sweep", "render.shadows=none,soft", "--out", tmp_path / "rep")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and "render.shadows" in lines[0], r.stderr
    assert not (tmp_path / "rep").exists()
