"""The skinning palette in chunks (render/poses/palette.py): a frame whose skinned
instances x palette texels exceed the (injected, small) chunk limit draws the
same pixels as one unchunked palette, in the full-detail path and in the
clusters drawer (with and without occlusion culling); plan_chunks cuts draws
in order into pieces that fit."""
from types import SimpleNamespace

import numpy as np
import pytest

from lod.clusters import mode as clusters_mode
from lod.full import mode as nolod
from lod.view import Camera
from render.poses.palette import PALETTE_MAX_TEXELS, plan_chunks
from render.renderer import Renderer
from sim.procedural import humanoid

SIZE = (160, 120)
BG = (0.1, 0.1, 0.12)


def test_plan_chunks_covers_every_instance_in_order_within_the_limit():
    sizes, per = [5, 0, 7, 1, 20], [9, 9, 12, 9, 30]
    chunks = plan_chunks(sizes, per, 100)
    flat = [p for ch in chunks for p in ch]
    for ch in chunks:
        assert sum(n * per[d] for d, _, n in ch) <= 100
        assert all(n > 0 for _, _, n in ch)
    # in draw order, each draw's pieces contiguous and complete
    assert [d for d, _, _ in flat] == sorted(d for d, _, _ in flat)
    for d, k in enumerate(sizes):
        mine = [(f, n) for dd, f, n in flat if dd == d]
        assert sum(n for _, n in mine) == k
        assert all(f == sum(n for _, n in mine[:i]) for i, (f, _) in enumerate(mine))
    assert plan_chunks([3, 4], [9, 9], 10 ** 6) == [[(0, 0, 3), (1, 0, 4)]]  # fits: one chunk, whole draws
    assert plan_chunks([], [], 10) == [] and plan_chunks([0], [9], 10) == []
    with pytest.raises(ValueError, match="one instance needs 30 texels"):
        plan_chunks([1], [30], 29)


@pytest.fixture(scope="module")
def crowd(gl_ctx):
    c = humanoid(1200, 3)
    full, fsel = nolod.build([c], ["h"], [30], {})
    creps, csel = clusters_mode.build([c], ["h"], [30], {"poe": 1.0}, cache=False)
    n = 48  # a 6 x 8 grid of agents at different animation times
    gx, gz = np.meshgrid(np.arange(8) * 0.9 - 3.2, np.arange(6) * 1.1 - 3.0)
    pos = np.stack([gx.ravel(), np.zeros(n), gz.ravel()], axis=1)
    st = SimpleNamespace(n=n, character=np.zeros(n, np.int64), clip=(np.arange(n) % 2).astype(np.int64),
                         anim_time=np.linspace(0.0, 0.9, n), position=pos, scale=np.ones(n),
                         heading=np.linspace(-3.0, 3.0, n))
    yield SimpleNamespace(c=c, full=full, fsel=fsel, creps=creps, csel=csel, st=st,
                          cam=Camera.look_at((0.0, 4.0, 9.0), (0.0, 0.8, 0.0)))


def _draw(gl_ctx, reps, dl, chunk_texels):
    r = Renderer(SIZE, ctx=gl_ctx)
    r.compute_raster = False  # the palette chunks of the hardware path (the compute rasteriser poses its own copies)
    try:
        if chunk_texels is not None:
            r.palette_chunk_texels = chunk_texels
        for rep in reps:
            r.upload(rep)
        r.draw(dl, background=BG)
        return r.read_pixels(), r._palette.passes
    finally:
        r.release()


def test_full_detail_in_palette_chunks_draws_the_unchunked_pixels(gl_ctx, crowd):
    dl = crowd.fsel.select(crowd.st, crowd.cam, SIZE)
    per = 3 * crowd.c.skeleton.n_joints
    ref, passes = _draw(gl_ctx, crowd.full, dl, None)
    assert passes == 1
    assert (np.abs(ref.astype(int) - np.round(np.asarray(BG) * 255)).max(axis=2) > 2).sum() > 500
    for per_chunk in (7, 1):  # 7 instances a chunk (batches cut mid-way), then one instance a chunk
        img, passes = _draw(gl_ctx, crowd.full, dl, per * per_chunk)
        assert passes == -(-crowd.st.n // per_chunk)
        assert np.array_equal(img, ref)


@pytest.mark.parametrize("occlusion", [False, True])
def test_clusters_in_palette_chunks_draw_the_unchunked_pixels(gl_ctx, crowd, occlusion):
    for rep in crowd.creps:
        rep.occlusion = occlusion
    dl = crowd.csel.select(crowd.st, crowd.cam, SIZE)
    per = 3 * crowd.c.skeleton.n_joints
    ref, _ = _draw(gl_ctx, crowd.creps, dl, None)
    img, passes = _draw(gl_ctx, crowd.creps, dl, per * 5)
    assert passes == -(-crowd.st.n // 5)
    assert np.array_equal(img, ref)


def test_chunk_limit_never_exceeds_what_the_shader_addresses(gl_ctx):
    r = Renderer((8, 8), ctx=gl_ctx)
    try:
        r.palette_chunk_texels = 1 << 40
        assert r._palette.chunk_texels == PALETTE_MAX_TEXELS
    finally:
        r.release()
