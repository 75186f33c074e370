"""Skinned programs specialised to the influences a mesh uses (render/vertex_format.py compact_influences,
``SKIN_INFLUENCES_n`` in shaders/poses/skinning.glsl): the compaction keeps every vertex's non-zero weights in order,
and the specialised draw is the 4-influence draw (the same terms in the same order; the shader compiler may
contract them into fused multiply-adds differently, so a few pixels may differ by a level)."""
import numpy as np
import pytest

from lod.full.mode import NoLodSelector
from lod.full.reps import build_rep
from lod.view import Camera
from render.renderer import Renderer
from render.vertex_format import compact_influences
from sim.procedural import humanoid
from sim.state import CrowdState


def test_compaction_moves_non_zero_weights_first_in_order():
    rng = np.random.default_rng(0)
    j = rng.integers(0, 30, (500, 4)).astype(np.uint16)
    w = rng.uniform(0.1, 1.0, (500, 4)).astype(np.float32)
    w[rng.uniform(size=(500, 4)) < 0.5] = 0.0
    w[np.all(w == 0, axis=1), 2] = 1.0
    jc, wc, n = compact_influences(j, w)
    assert n == int((w != 0).sum(1).max())
    for v in range(500):
        nz = np.flatnonzero(w[v])
        k = len(nz)
        assert np.array_equal(wc[v, :k], w[v, nz]) and np.array_equal(jc[v, :k], j[v, nz])
        assert np.all(wc[v, k:] == 0)
    assert compact_influences(np.zeros((0, 4)), np.zeros((0, 4)))[2] == 1


def _one_influence(ch):
    m = ch.mesh
    top = np.asarray(m.joints)[np.arange(m.n_vertices), np.argmax(m.weights, 1)]
    m.joints = np.zeros_like(m.joints)
    m.joints[:, 0] = top
    m.weights = np.zeros_like(m.weights)
    m.weights[:, 0] = 1.0
    return ch


@pytest.mark.parametrize("rigid", [True, False])
@pytest.mark.parametrize("skinning", ["palette", "direct"])
def test_specialised_program_draws_the_same_image(gl_ctx, rigid, skinning):
    ch = humanoid(2500, seed=6)
    if rigid:
        _one_influence(ch)
    else:  # spread the weights over the slots, zeros in between (compaction has work to do)
        m = ch.mesh
        m.joints = np.asarray(m.joints)[:, [0, 3, 1, 2]].copy()
        m.weights = np.asarray(m.weights)[:, [0, 3, 1, 2]].copy()
    rep = build_rep(ch, key="inf:h")
    st = CrowdState.empty(6)
    st.position[:, 0] = np.arange(6) * 0.9 - 2.2
    st.heading[:] = np.linspace(0, 5, 6)
    st.anim_time[:] = 0.17 * np.arange(6)
    cam = Camera.look_at((0.0, 1.6, 4.0), (0.0, 0.9, 0.0), fov_y=50.0, near=0.1, far=50.0)
    size = (256, 160)
    images, labels = [], []
    for special in (True, False):
        with Renderer(size, ctx=gl_ctx, debug=True, skinning=skinning) as r:
            r.specialize_influences = special
            r.upload(rep)
            r.draw(NoLodSelector([rep]).select(st, cam, size))
            images.append(r.read_pixels().copy())
            labels.append(r._reps["inf:h"].defines)
    n = compact_influences(rep.joints, rep.weights)[2]
    assert (n == 1) == rigid and n < 4
    assert labels[0] == (f"SKIN_INFLUENCES_{n}",) and labels[1] == ()
    assert np.any(images[0] != images[0][0, 0])
    a, b = (x.astype(np.int64) for x in images)
    assert (np.abs(a - b).max(axis=2) > 1).mean() <= 1e-3
    mse = np.mean((a - b) ** 2.0)
    assert mse == 0 or 10 * np.log10(255.0 ** 2 / mse) >= 50.0, 10 * np.log10(255.0 ** 2 / mse)
