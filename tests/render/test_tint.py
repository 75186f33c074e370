"""Colour-by debugging (VDR-AM Fig. 11): a batch tint changes colours, never coverage."""
import numpy as np
import pytest

from tiny_characters import tiny_skinned

from lod.debug_colors import COLOR_BY, LEVEL_COLORS, REPRESENTATION_COLORS, apply_tints
from lod.full.mode import NoLodSelector
from lod.full.reps import build_rep
from lod.view import Camera
from render.renderer import Renderer
from sim.state import CrowdState

W, H = 160, 120


@pytest.fixture(scope="module")
def setup(gl_ctx):
    rep = build_rep(tiny_skinned(), fps=30)
    r = Renderer((W, H), ctx=gl_ctx, debug=True)
    r.upload(rep)
    yield r, rep
    r.release()


def _draw(r, rep, by):
    cam = Camera.look_at((1.0, 2.0, 7.0), (0.0, 1.5, 0.0), fov_y=50)
    st = CrowdState.empty(1)
    dl = apply_tints(NoLodSelector([rep]).select(st, cam, (W, H)), by)
    r.draw(dl, background=(0, 0, 0))
    return dl, r.read_pixels().astype(np.int32)


def test_tint_recolours_the_same_pixels(setup):
    r, rep = setup
    dl0, plain = _draw(r, rep, "none")
    assert all(b.tint is None for b in dl0.batches)
    for by in ("representation", "level"):
        dl, tinted = _draw(r, rep, by)
        assert all(b.tint is not None and len(b.tint) == 4 for b in dl.batches)
        fg0, fg1 = plain.max(axis=2) > 8, tinted.max(axis=2) > 8
        assert fg0.sum() > 200
        # coverage is unchanged, colours are not
        assert (fg0 != fg1).sum() <= 0.01 * fg0.sum()
        assert np.abs(plain - tinted)[fg0].mean() > 10


def test_level_tint_is_the_level_colour_and_unknown_mode_is_refused(setup):
    r, rep = setup
    cam = Camera.look_at((1.0, 2.0, 7.0), (0.0, 1.5, 0.0))
    dl = NoLodSelector([rep]).select(CrowdState.empty(1), cam, (W, H))
    dl.batches[0].level = 99
    apply_tints(dl, "level")
    assert dl.batches[0].tint[:3] == LEVEL_COLORS[-1]
    apply_tints(dl, "representation")
    assert dl.batches[0].tint[:3] == REPRESENTATION_COLORS["none"]
    assert "level" in COLOR_BY
    with pytest.raises(ValueError, match="colour by"):
        apply_tints(dl, "rainbow")


# ------------------------------------------------------------------ per-instance colour words (render/tint.py)
from render.shaders import load_source  # noqa: E402
from render.tint import apply_tint, batch_words, debug_word  # noqa: E402
from lod.variation import (MODE_HSV, MODE_PALETTE, hsv_to_rgb, pack_hsv, rgb_to_hsv, variation_table,  # noqa: E402
                           variation_words)

_TINT_VS = """#version 330 core
in vec4 in_color;
in uvec2 in_words;
out vec3 v_out;
#include "tint.glsl"
void main() { v_out = tint_color(in_color, in_words).rgb; }
"""


def _gl_tint(ctx, colors, words):
    """tint_color of tint.glsl run on the GPU (transform feedback) for each (colour, words) row."""
    src = _TINT_VS.replace('#include "tint.glsl"', load_source("tint.glsl"))
    prog = ctx.program(vertex_shader=src, varyings=["v_out"])
    n = colors.shape[0]
    cb = ctx.buffer(np.ascontiguousarray(colors, np.float32).tobytes())
    wb = ctx.buffer(np.ascontiguousarray(words, np.uint32).tobytes())
    out = ctx.buffer(reserve=n * 12)
    vao = ctx.vertex_array(prog, [(cb, "4f", "in_color"), (wb, "2u", "in_words")])
    try:
        vao.transform(out, vertices=n)
        return np.frombuffer(out.read(), np.float32).reshape(n, 3).astype(np.float64)
    finally:
        for o in (vao, out, wb, cb, prog):
            o.release()


def _cases():
    rng = np.random.default_rng(5)
    n = 400
    col = np.concatenate([rng.uniform(0, 1, (n, 4)),
                          # black, greys, white, pure primaries (zero saturation / zero value / hue wrap)
                          [[0, 0, 0, 1], [0.5, 0.5, 0.5, 1], [1, 1, 1, 1], [0.2, 0.2, 0.2, 0.5],
                           [1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1], [1, 0, 1, 1]]])
    m = col.shape[0]
    w = np.zeros((m, 2), np.uint32)
    w[:, 0] = np.where(np.arange(m) % 3 == 0, pack_hsv(rng.uniform(-0.5, 0.5, m), rng.uniform(0, 1.9, m),
                                                       rng.uniform(0, 1.9, m)),
                       np.where(np.arange(m) % 3 == 1, variation_words(3, np.arange(m), palette=rng.uniform(0, 1, (5, 3))),
                                0))
    w[::4, 1] = debug_word((0.95, 0.35, 0.2, 0.75))
    return col, w


def test_glsl_tint_matches_the_numpy_reference_and_stays_finite(gl_ctx):
    col, w = _cases()
    gpu = _gl_tint(gl_ctx, col, w)
    ref = apply_tint(col, w)
    assert np.isfinite(gpu).all() and np.isfinite(ref).all()
    assert np.abs(gpu - ref).max() < 2e-4
    assert ((gpu >= -1e-6) & (gpu <= 1 + 1e-6)).all()


def test_hue_shift_leaves_black_and_grey_unchanged_without_nan(gl_ctx):
    greys = np.array([[0, 0, 0, 1], [0.25, 0.25, 0.25, 1], [0.7, 0.7, 0.7, 1], [1, 1, 1, 1]], np.float64)
    w = np.zeros((4, 2), np.uint32)
    w[:, 0] = pack_hsv([0.45, -0.3, 0.2, 0.49], 1.5, 1.0)  # hue and saturation change nothing without chroma
    gpu = _gl_tint(gl_ctx, greys, w)
    assert np.isfinite(gpu).all()
    assert np.abs(gpu - greys[:, :3]).max() < 1e-5
    assert np.isfinite(rgb_to_hsv(greys[:, :3])).all()


def test_mask_zero_keeps_the_colour_and_words_zero_are_identity():
    col, w = _cases()
    keep = col.copy()
    keep[:, 3] = 0.0
    out = apply_tint(keep, w * np.array([1, 0], np.uint32))
    assert np.abs(out - keep[:, :3]).max() < 1e-12
    assert np.abs(apply_tint(col, np.zeros(2, np.uint32)) - col[:, :3]).max() < 1e-12
    rgb = np.random.default_rng(1).uniform(0, 1, (50, 3))
    assert np.abs(hsv_to_rgb(rgb_to_hsv(rgb)) - rgb).max() < 1e-6


def test_variation_is_a_function_of_seed_and_agent_only():
    ids = np.arange(1000)
    a = variation_words(1, ids, hue=0.1, saturation=0.2, value=0.2)
    assert (a >> 24 == MODE_HSV).all()
    assert np.array_equal(a, variation_words(1, ids, hue=0.1, saturation=0.2, value=0.2))
    perm = np.random.default_rng(0).permutation(1000)  # any order, any subset: the same word per agent
    assert np.array_equal(variation_words(1, ids[perm], hue=0.1, saturation=0.2, value=0.2), a[perm])
    b = variation_words(2, ids, hue=0.1, saturation=0.2, value=0.2)
    assert (a != b).mean() > 0.95
    assert np.unique(a).size > 900  # agents differ
    hue = ((a & 255).astype(np.int64) - 128) / 256.0
    assert np.abs(hue).max() <= 0.1 + 1 / 256 and hue.std() > 0.04  # spread over +-hue
    pal = [(1, 0, 0), (0, 1, 0), (0, 0, 1)]
    p = variation_words(1, ids, palette=pal)
    assert (p >> 24 == MODE_PALETTE).all()
    counts = np.bincount(np.argmax(np.stack([(p >> (8 * k)) & 255 for k in range(3)], 1), 1), minlength=3)
    assert counts.min() > 250  # each palette entry taken about equally
    table = variation_table(1, np.array([0, 1, 0, 1]), [None, {"hue": 0.1}])
    assert table[0] == 0 and table[2] == 0 and table[1] != 0 and table[3] != 0


def test_batch_words_follow_ids_and_carry_the_debug_tint():
    from lod.drawlist import DrawBatch

    table = np.array([11, 22, 33], np.uint32)
    b1 = DrawBatch("none:x", 0, np.array([2, 0], np.int32), np.zeros((2, 16), np.float32))
    b2 = DrawBatch("none:x", 0, np.array([-1, 1, 7], np.int32), np.zeros((3, 16), np.float32),
                   tint=(1.0, 0.0, 0.0, 0.75))
    w = batch_words([b1, b2], table)
    assert w[:, 0].tolist() == [33, 11, 0, 22, 0]  # scenery (id < 0) and unknown ids: no variation
    assert w[:2, 1].tolist() == [0, 0] and (w[2:, 1] == debug_word((1.0, 0.0, 0.0, 0.75))).all()
    assert (batch_words([b1], None)[:, 0] == 0).all()
    scenery = DrawBatch("static:terrain", 0, np.array([0, 1], np.int32), np.zeros((2, 16), np.float32))
    assert (batch_words([scenery], table) == 0).all()  # ids of scenery are not agents
