"""Hard cases through every LOD mode (none, triangles, clusters, points, auto).

Complements test_hard_cases.py (degenerate meshes, the shrinking sphere, a
camera inside a character's bounds, near plane through the crowd, 1e7 m and
1e6 m in every mode) with: a joint scaled to zero and 180-degree rotations
between keys, and a crowd packed into one grid cell, each through every mode's
build, selection and draw. Invariants: finite DrawList instance data (the debug
renderer also refuses NaN/Inf), finite GPU buffers (the instance buffer read
back, and for triangle representations the vertex shader's outputs captured
by transform feedback), non-blank images.
"""
from __future__ import annotations

import numpy as np
import pytest

from hc_util import check_frame, crowd, look
from tiny_characters import tiny_skinned

from lod.modes import mode_module
from render.renderer import Renderer
from sim.clip import Channel, Clip

MODES = ["none", "triangles", "clusters", "points", "auto"]


def _quat_z(deg):
    a = np.radians(np.asarray(deg, np.float64)) * 0.5
    return np.stack([0 * a, 0 * a, np.sin(a), np.cos(a)], axis=-1)


def _stressed_character():
    """tiny_skinned with two more clips: "vanish" (joint 1 scaled to zero
    mid-clip) and "flip" (joint 1 turns 180 degrees between consecutive keys,
    then back to the antipode of its first key)."""
    ch = tiny_skinned("stressed")
    t = np.array([0.0, 0.5, 1.0])
    ch.clips["vanish"] = Clip("vanish", 1.0, [Channel(1, "scale", t, np.array([[1, 1, 1], [0, 0, 0], [1, 1, 1.0]]))],
                              loop=True)
    t4 = np.array([0.0, 0.4, 0.8, 1.2])
    q = _quat_z([0.0, 180.0, 360.0, 540.0])  # 360 deg: -q0, the same rotation as the first key
    ch.clips["flip"] = Clip("flip", 1.2, [Channel(1, "rotation", t4, q), Channel(2, "rotation", t4, q[::-1].copy())],
                            loop=True)
    return ch


def _build(mode, chars, tmp_path, monkeypatch):
    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path))
    mod = mode_module(mode)
    params = {k: p.default for k, p in getattr(mod, "PARAMS", {}).items()}
    return mod.build(chars, [c.name for c in chars], [30] * len(chars), params)


@pytest.mark.parametrize("mode", MODES)
def test_zero_scale_joint_and_180_degree_keys_in_every_lod_mode(gl_ctx, mode, tmp_path, monkeypatch):
    """Both clips (a joint scaled to zero; 180-degree keys folding the column
    onto itself, which gives zero-area triangles to the QEM builds) in every mode."""
    ch = _stressed_character()
    reps, sel = _build(mode, [ch], tmp_path, monkeypatch)
    st = crowd(16, spacing=1.5)
    st.clip[:8] = ch.clip_index("vanish")
    st.clip[8:] = ch.clip_index("flip")
    size = (96, 64)
    cams = [look((2, 3, 12), (2, 1, 2)),                      # overview
            look((0.0, 1.5, 0.0), (0.0, 1.5, 5.0), near=0.01),  # inside agent 0's bounds
            look((2, 40, 60), (2, 1, 2))]                      # far: coarse levels
    blank = []
    with Renderer(size, ctx=gl_ctx, debug=True) as r:
        for rep in reps:
            r.upload(rep)
        # sample exactly the zero-scale key (t = 0.5) and the 180-degree keys (0.4, 0.8)
        for f, t in enumerate([0.4, 0.5, 0.8, 1.2, 0.25, 0.65]):
            st.anim_time[:] = t + 0.01 * np.arange(16) * (f % 2)
            dl = sel.select(st, cams[f % len(cams)], size)
            r.draw(dl)
            check_frame(r, dl)
            blank.append(r.read_pixels().std() == 0)
    assert not all(blank)


@pytest.mark.parametrize("mode", MODES)
def test_crowd_packed_into_one_grid_cell_in_every_lod_mode(gl_ctx, mode, tmp_path, monkeypatch):
    """100,000 agents within half a metre: every mode selects them with finite
    instance data; 1,000 of them are drawn (finite GPU buffers, an image)."""
    ch = tiny_skinned("packed")
    reps, sel = _build(mode, [ch], tmp_path, monkeypatch)
    rng = np.random.default_rng(4)
    size = (64, 48)
    cam = look((0.2, 2.0, 9.0), (0.2, 1.0, 0.2))
    big = crowd(100_000, spacing=0.0)
    big.position[:, [0, 2]] += rng.uniform(0.0, 0.5, (100_000, 2))
    big.anim_time[:] = rng.uniform(0.0, 1.0, 100_000)
    dl = sel.select(big, cam, size)
    assert sum(b.n_instances for b in dl.batches) >= 1
    for b in dl.batches:
        assert np.isfinite(np.asarray(b.instance_data, np.float64)).all()
    small = crowd(1_000, spacing=0.0)
    small.position[:] = big.position[:1_000]
    small.anim_time[:] = big.anim_time[:1_000]
    with Renderer(size, ctx=gl_ctx, debug=True) as r:
        for rep in reps:
            r.upload(rep)
        for _ in range(2):
            dl = sel.select(small, cam, size)
            r.draw(dl)
            check_frame(r, dl)
        assert r.read_pixels().std() > 0


def test_180_degree_keys_in_the_triangles_chain(tmp_path, monkeypatch):
    """Zero-area triangles of the folded pose reach qem's point-triangle distance
    (once a ZeroDivisionError in the compiled kernel): the chain builds with
    finite errors."""
    reps, _ = _build("triangles", [_stressed_character()], tmp_path, monkeypatch)
    chains = [r for r in reps if hasattr(r, "level_error")]
    assert chains
    for rep in chains:
        assert np.isfinite(rep.level_error).all() and (np.diff(rep.level_error) >= 0).all()


@pytest.mark.parametrize("mode", ["triangles", "clusters", "auto"])
def test_geomorphs_of_the_stressed_character(gl_ctx, mode, tmp_path, monkeypatch):
    """Keyframed selection (n = 3) geomorphs chain levels and cluster cuts of the zero-scale and
    folded clips while the camera dollies in from far: finite instance data and morph weights,
    every agent drawn, images not blank."""
    from lod.temporal.selection import KeyframedSelector

    ch = _stressed_character()
    reps, inner = _build(mode, [ch], tmp_path, monkeypatch)
    sel = KeyframedSelector(inner, n=3, mode="current")
    st = crowd(16, spacing=1.5)
    st.clip[:8] = ch.clip_index("vanish")
    st.clip[8:] = ch.clip_index("flip")
    size = (96, 64)
    morphs = 0
    with Renderer(size, ctx=gl_ctx, debug=True) as r:
        for rep in reps:
            r.upload(rep)
        for f in range(9):
            st.anim_time[:] = 0.4 + 0.05 * f  # across the zero-scale key (0.5) and the 180-degree one (0.8)
            dl = sel.select(st, look((2, 3 + 4 * (8 - f), 12 + 10 * (8 - f)), (2, 1, 2)), size)
            r.draw(dl)
            check_frame(r, dl)
            for b in dl.batches:
                for w in (getattr(b, "morph_weight", None), (getattr(b, "morph", None) or (0, 0.0))[1:]):
                    assert w is None or np.isfinite(np.asarray(w, np.float64)).all()
            morphs += dl.stats["geomorphs"]
            assert r.read_pixels().std() > 0
    assert morphs > 0 or mode == "auto"
