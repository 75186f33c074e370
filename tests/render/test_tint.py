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
