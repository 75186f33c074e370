"""Keyframed crowd LOD in a real run: ``[lod] keyframe_every`` is valid for every
mode, the engine selects only on keyframes and logs it in frames.csv, and the
live interval of the fly-through's settings reaches the selector."""
import csv

import numpy as np
import pytest
from crowd_testutil import run_cli, tiny_scene

from crowd.engine import Engine
from crowd.scene import load_scene


def _scene(tmp_path, mode="triangles", extra="", frames=9):
    p = tmp_path / "k.toml"
    p.write_text(tiny_scene(replace={"frames = 3": f"frames = {frames}", "png_every = 1": "png_every = 0",
                                     'mode = "none"': f'mode = "{mode}"\n{extra}'}))
    return p


def test_keyframed_triangles_run_selects_every_nth_frame(tmp_path):
    out = tmp_path / "out"
    r = run_cli("run", _scene(tmp_path, extra="keyframe_every = 4\nkeyframe_extrapolation = \"current\""),
                "--out", out, "--quiet")
    assert r.returncode == 0, r.stderr
    rows = list(csv.DictReader(open(out / "frames.csv")))
    assert [float(x["lod_keyframe"]) for x in rows] == [1.0 if f % 4 == 0 else 0.0 for f in range(9)]
    assert all(int(float(x["instances"])) == 4 for x in rows)  # the 2x2 grid, never dropped
    sel = [float(x["lod_selection_ms"]) for x in rows]
    assert all(s >= 0.0 for s in sel)


@pytest.mark.parametrize("mode", ["none", "triangles", "points", "clusters", "auto"])
def test_keyframe_every_is_valid_for_every_mode(tmp_path, mode):
    s = load_scene(_scene(tmp_path, mode=mode, extra="keyframe_every = 3"))
    assert dict(s.lod_common) == {"keyframe_every": 3, "keyframe_extrapolation": "extrapolated",
                                  "keyframe_geomorph": True, "pose_rate": "key"}  # pose_rate: lod.poses




@pytest.mark.parametrize("line,needle", [("keyframe_every = 0", "lod.keyframe_every"),
                                         ("keyframe_every = 2.5", "lod.keyframe_every"),
                                         ('keyframe_extrapolation = "future"', "lod.keyframe_extrapolation")])
def test_bad_keyframe_keys_are_one_line_errors(tmp_path, line, needle):
    r = run_cli("validate", _scene(tmp_path, extra=line))
    assert r.returncode == 2 and needle in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_default_is_per_frame_selection(tmp_path):
    with Engine(load_scene(_scene(tmp_path)), quiet=True) as e:
        assert type(e.selector).__name__ == "TrianglesSelector"
        assert e.settings.keyframe_interval == 1


def test_live_keyframe_interval_and_occlusion_are_applied(tmp_path):
    from lod.temporal.selection import KeyframedSelector

    with Engine(load_scene(_scene(tmp_path, mode="clusters")), quiet=True) as e:
        cam = e.camera_at(0.0)
        e.select(cam, (64, 48))
        e.settings.keyframe_interval = 3
        keys = []
        for _ in range(6):
            e.step()
            dl = e.select(cam, (64, 48))
            keys.append(dl.stats["keyframe"])
        assert isinstance(e.selector, KeyframedSelector) and e.selector.n == 3
        assert keys == [True, False, False, True, False, False]
        e.settings.poe = 7.0
        e.select(cam, (64, 48))
        assert e.selector.inner.poe == 7.0  # live settings pass through the wrapper
        e.settings.keyframe_interval = 1
        dl = e.select(cam, (64, 48))
        assert "keyframe" not in dl.stats and e.selector.n == 1
        e.settings.occlusion = True
        e.select(cam, (64, 48))
        assert all(r.occlusion for r in e.reps if getattr(r, "kind", "") == "clusters")
        e.settings.occlusion = False
        e.select(cam, (64, 48))
        assert not any(r.occlusion for r in e.reps if getattr(r, "kind", "") == "clusters")
        assert np.isfinite(e.world.state.position).all()


@pytest.mark.parametrize("mode", ["points", "clusters", "auto", "none"])
def test_keyframed_engine_frames_in_every_mode(tmp_path, mode):
    """Every mode's selector can be keyframed: the engine wraps it, draws every
    agent on every frame, selects only on keyframes and renders without error."""
    from lod.temporal.selection import KeyframedSelector

    with Engine(load_scene(_scene(tmp_path, mode=mode, extra="keyframe_every = 3")), quiet=True) as e:
        assert isinstance(e.selector, KeyframedSelector) and e.selector.n == 3
        r = e.open_renderer()
        statics = [(s.key, np.eye(4)) for s in e.statics]
        keys = []
        for _ in range(5):
            e.step()
            dl = e.selector.select(e.world.state, e.camera_at(e.world.time), e.scene.render.size, statics=statics)
            ids = np.concatenate([b.instance_ids for b in dl.batches])
            assert np.array_equal(np.unique(ids[ids >= 0]), np.arange(e.world.state.n))
            keys.append(dl.stats["keyframe"])
            r.draw(dl)
            assert r.read_pixels().max() > 0
        assert keys == [True, False, False, True, False]


def test_keyframed_clusters_run_geomorphs_changed_cuts(tmp_path):
    """A camera dollying in changes the instances' cluster cuts: in-between frames geomorph
    them (frames.csv lod_geomorphs), and with keyframe_geomorph = false they fade instead."""
    counts = {}
    for morph in ("true", "false"):
        p = tmp_path / f"g_{morph}.toml"
        p.write_text(tiny_scene(replace={
            "frames = 3": "frames = 12", "png_every = 1": "png_every = 0", "size = [64, 48]": "size = [160, 120]",
            "position = [1.0, 2.0, 7.0]\ntarget = [1.0, 0.8, 1.0]":
                "keys = [{ time = 0.0, position = [1.0, 1.5, 40.0], target = [1.0, 0.9, 0.0] },\n"
                "        { time = 0.6, position = [1.0, 1.5, 4.0], target = [1.0, 0.9, 0.0] }]",
            'mode = "none"': f'mode = "clusters"\npoe = 1.0\nkeyframe_every = 4\nkeyframe_extrapolation = "current"\n'
                             f'keyframe_geomorph = {morph}'}))
        out = tmp_path / f"out_{morph}"
        r = run_cli("run", p, "--out", out, "--quiet")
        assert r.returncode == 0, r.stderr
        rows = list(csv.DictReader(open(out / "frames.csv")))
        counts[morph] = (sum(float(x["lod_geomorphs"]) for x in rows), sum(float(x["lod_transitions"]) for x in rows))
        assert all(int(float(x["instances"])) == 4 for x in rows)
    assert counts["true"][0] > 0 and counts["true"][0] == counts["true"][1]
    assert counts["false"][0] == 0 and counts["false"][1] > 0


@pytest.mark.parametrize("mode", ["points", "auto"])
def test_keyframed_selection_turns_the_far_tier_off(tmp_path, mode):
    """A keyframed selection blends instance rows between its keyframe lists; a far splat's row is not one
    (lod/far): with keyframe_every > 1 the far tier is off, and every frame draws."""
    s = load_scene(_scene(tmp_path, mode=mode, extra="keyframe_every = 2\nfar_pixels = 8.0", frames=3))
    with Engine(s, quiet=True) as eng:
        assert eng.selector.inner.far is None
        eng.run(frames=3, out_dir=tmp_path / "out")
    s1 = load_scene(_scene(tmp_path, mode=mode, extra="far_pixels = 8.0", frames=3))
    with Engine(s1, quiet=True) as eng:
        assert eng.selector.far is not None
