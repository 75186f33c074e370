"""Bounded driver memory: large instanced draws are split into submissions of at
most ``Renderer.max_triangles_in_flight`` triangles (render.renderer, "Bounded
driver memory"), and the split draws exactly the same image as one draw."""
import numpy as np

from hc_util import crowd, look
from tiny_characters import tiny_keyframed, tiny_skinned

from lod.full.mode import NoLodSelector
from lod.full.reps import build_rep
from render.renderer import MAX_TRIANGLES_IN_FLIGHT, Renderer


def _draw(ctx, reps, state, cam, size, budget, skinning="palette"):
    sel = NoLodSelector(reps)
    with Renderer(size, ctx=ctx, debug=True, skinning=skinning) as r:
        r.max_triangles_in_flight = budget
        for rep in reps:
            r.upload(rep)
        out = []
        for t in (0.1, 0.45):
            state.anim_time[:] = t + 0.037 * np.arange(state.n)  # every instance its own pose
            dl = sel.select(state, cam, size)
            r.draw(dl)
            batches = [b.n_instances for b in dl.batches if b.n_instances]
            out.append((r.read_pixels().copy(), r.last_submissions, batches,
                        r.last_timings["samples_passed"]))
    return out


def test_split_submissions_draw_the_same_image(gl_ctx):
    chars = [tiny_skinned(), tiny_keyframed()]
    reps = [build_rep(c, key=f"dm:{i}") for i, c in enumerate(chars)]
    st = crowd(30, spacing=1.2)
    st.character[15:] = 1
    cam = look((3, 3, 12), (3, 1, 3))
    size = (96, 64)
    for skinning in ("palette", "direct"):
        whole = _draw(gl_ctx, reps, st, cam, size, None, skinning)
        split = _draw(gl_ctx, reps, st, cam, size, 1, skinning)  # one instance per submission
        for (im_w, n_w, batches, s_w), (im_s, n_s, _, s_s) in zip(whole, split):
            assert im_w.std() > 0
            assert n_w == len(batches)  # no limit: one submission per batch
            assert n_s == sum(batches) and n_s > 2 * len(batches)  # split: one instance per submission
            assert np.array_equal(im_w, im_s), skinning
            assert s_w == s_s  # the same fragments passed the depth test


def test_default_limit_splits_only_large_draws(gl_ctx):
    """A few small characters: one submission per batch; the same crowd with the
    limit set below one batch's triangles: more submissions, same image."""
    assert MAX_TRIANGLES_IN_FLIGHT >= 10_000
    ch = tiny_skinned()
    rep = build_rep(ch, key="dm:one")
    st = crowd(12, spacing=1.5)
    cam = look((2, 3, 10), (2, 1, 2))
    (im, n, batches, _), _ = _draw(gl_ctx, [rep], st, cam, (64, 48), MAX_TRIANGLES_IN_FLIGHT)
    assert n == len(batches)
    tri = int(np.asarray(rep.indices).size) // 3
    (im2, n2, batches2, _), _ = _draw(gl_ctx, [rep], st, cam, (64, 48), 5 * tri)  # 5 instances per submission
    assert batches2 == batches and n2 == sum(-(-k // 5) for k in batches) > len(batches)
    assert np.array_equal(im, im2)
