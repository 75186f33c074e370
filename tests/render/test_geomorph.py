"""Geomorphs of LOD chain levels (lod/chains/mode.py TriangleDrawBatch.morph,
shaders/poses/skinned_morph.vert and skinned_direct_morph.vert): a level drawn with
weight 0 is that level pixel for pixel, with weight 1 the coarser level pixel for
pixel, in between neither; both skinning paths."""
from types import SimpleNamespace

import numpy as np
import pytest

from lod.chains import chain as tm_chain
from lod.chains import mode as tm
from lod.view import Camera
from render.renderer import Renderer
from sim.procedural import humanoid

SIZE = (320, 240)
BG = (0.1, 0.1, 0.12)


@pytest.fixture(scope="module")
def chain():
    c = humanoid(2500, 0)
    reps, sel = tm.build([c], ["h"], [30], {"poe": 1.0, "levels": 6}, cache=False)
    return reps[0], sel


def _crowd():
    return SimpleNamespace(n=3, character=np.zeros(3, np.int64), clip=np.array([0, 1, 0]),
                           anim_time=np.array([0.1, 0.45, 0.8]),
                           position=np.array([[0, 0, 0], [1.2, 0, -1.5], [-1.0, 0, 0.8]], float),
                           scale=np.ones(3), heading=np.array([0.0, 1.0, 2.5]))


def _image(r, sel, rep, level, morph=None):
    dl = sel.select(_crowd(), Camera.look_at((0, 1.2, 5.0), (0, 0.9, 0)), SIZE)
    dl.batches = [tm_chain.TriangleDrawBatch(b.rep, b.part, b.instance_ids, b.instance_data, level=level,
                                       index_range=(3 * int(rep.level_first[level]), 3 * int(rep.level_count[level])),
                                       morph=morph) for b in dl.batches]
    r.draw(dl, background=BG)
    return r.read_pixels()


@pytest.mark.parametrize("skinning", ["palette", "direct"])
def test_chain_level_geomorph_ends_are_the_two_levels(chain, gl_ctx, skinning):
    rep, sel = chain
    assert rep.collapse_next is not None and rep.n_levels >= 5
    r = Renderer(SIZE, ctx=gl_ctx, skinning=skinning)
    try:
        r.upload(rep)
        for fine, coarse in ((0, 2), (1, 4), (3, 4)):
            a, b = _image(r, sel, rep, fine), _image(r, sel, rep, coarse)
            assert not np.array_equal(a, b)
            assert np.array_equal(_image(r, sel, rep, fine, (coarse, 0.0)), a)
            assert np.array_equal(_image(r, sel, rep, fine, (coarse, 1.0)), b)
            mid = _image(r, sel, rep, fine, (coarse, 0.5))
            assert not np.array_equal(mid, a) and not np.array_equal(mid, b)
            assert np.isfinite(mid).all()
    finally:
        r.release()


def test_geomorph_of_a_rep_without_collapses_is_a_clear_error(chain, gl_ctx):
    import dataclasses

    rep, sel = chain
    bare = dataclasses.replace(rep, collapse_next=None, collapse_level=None)
    r = Renderer(SIZE, ctx=gl_ctx)
    try:
        r.upload(bare)
        with pytest.raises(ValueError, match="vertex collapses"):
            _image(r, sel, bare, 1, (3, 0.5))
    finally:
        r.release()
