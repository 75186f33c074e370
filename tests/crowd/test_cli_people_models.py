"""``crowd build`` and ``crowd run`` on the characters people bring (issue 20): the report's mixed rig and a
statue without animation build and run; what cannot be supported is one sentence naming the file, exit code 2,
and nothing written, from ``crowd build`` as from ``crowd run``."""
import csv

import pytest
from awkward_gltf import exploding, lines_only, mixed_rig, statue
from crowd_testutil import run_cli

SCENE = """\
name = "people"
seed = 1
dt = 0.05
frames = 3
effects = ["animation"]

[[characters]]
name = "guest"
file = "{file}"

[[placement]]
kind = "grid"
character = "guest"
rows = 2
cols = 2
spacing = [2.5, 2.5]

[camera]
position = [2.0, 2.0, 9.0]
target = [1.2, 0.9, 1.2]

[render]
size = [64, 48]
png_every = 0

[lod]
mode = "{mode}"
"""
WRITERS = {"mixed": mixed_rig, "statue": statue, "exploding": exploding, "lines": lines_only}


def _scene(tmp_path, model, mode):
    glb = WRITERS[model](tmp_path / f"{model}.glb")
    path = tmp_path / f"{model}-{mode}.toml"
    path.write_text(SCENE.format(file=glb.name, mode=mode))
    return glb, path


@pytest.mark.parametrize("model, mode", [("mixed", "clusters"), ("mixed", "auto"), ("statue", "none"),
                                         ("statue", "clusters"), ("statue", "points")])
def test_build_then_run(tmp_path, monkeypatch, model, mode):
    """The mixed rig once stopped ``crowd build --mode clusters`` and ``crowd run`` (clusters, auto) with a
    traceback; the statue stopped ``crowd build`` (no clip) and ``crowd run`` refused it."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("CROWD_CACHE_DIR", str(cache))
    glb, scene = _scene(tmp_path, model, mode)
    if mode != "none":
        r = run_cli("build", glb, "--mode", mode, "--cluster", "none", "--quiet", cwd=tmp_path)
        assert r.returncode == 0 and r.stderr == "", r.stderr
        assert any(cache.iterdir())
    r = run_cli("run", scene, "--out", tmp_path / "out", "--quiet", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr
    with open(tmp_path / "out" / "frames.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 3 and all(int(x["instances"]) == 4 for x in rows)
    assert all(float(x["triangles"]) + float(x["points"]) > 0 for x in rows)


@pytest.mark.parametrize("model, what", [("exploding", "beyond the float32 range"),
                                         ("lines", "primitive mode 1 (LINES) is not supported")])
@pytest.mark.parametrize("command", ["build", "run"])
def test_unsupported_asset_is_one_sentence_exit_2_nothing_written(tmp_path, monkeypatch, model, what, command):
    cache = tmp_path / "cache"
    monkeypatch.setenv("CROWD_CACHE_DIR", str(cache))
    glb, scene = _scene(tmp_path, model, "clusters")
    if command == "build":
        r = run_cli("build", glb, "--cluster", "none", cwd=tmp_path)  # every cached mode
    else:
        r = run_cli("run", scene, "--out", tmp_path / "out", cwd=tmp_path)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    if command == "build":  # the file named on the command line: its name
        assert lines[0].startswith(f"crowd {command}: error: {glb.name}: ") and what in lines[0], lines[0]
    else:  # a scene's character: the scene, its key and the file's path (issue 48)
        assert lines[0].startswith(f"crowd {command}: error: {scene}: characters[0].file: ") and what in lines[0]
        assert str(glb.name) in lines[0], lines[0]
    assert r.stdout == ""
    assert not (tmp_path / "out").exists()
    assert not cache.exists() or not any(p.suffix == ".npz" for p in cache.rglob("*"))
