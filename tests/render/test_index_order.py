"""Triangle order for llvmpipe's vertex cache (render/index_order.py): the numba cache model matches its
Python reference, the order is a permutation of whole triangles that never shades more vertices, and the
reordered full-detail draw gives the same image."""
import numpy as np

from lod.full.mode import NoLodSelector
from lod.full.reps import build_rep
from lod.view import Camera
from render.index_order import morton_order, vertex_cache_order, vsplit_shaded, vsplit_shaded_reference
from render.renderer import Renderer
from sim.procedural import humanoid
from sim.state import CrowdState


def test_cache_model_matches_reference_and_edge_cases():
    rng = np.random.default_rng(1)
    for n, top in ((0, 10), (3, 5), (999, 300), (5000, 2000)):
        idx = rng.integers(0, top, n - n % 3)
        assert vsplit_shaded(idx) == vsplit_shaded_reference(idx)
    assert vsplit_shaded(np.arange(3000)) == 3000  # no reuse
    assert vsplit_shaded(np.zeros(3000, np.int64)) == 3  # one vertex: once per segment of 1,023 indices


def test_order_is_a_permutation_of_whole_triangles_and_never_worse():
    m = humanoid(20000, seed=3).mesh
    tri = np.asarray(m.indices).reshape(-1, 3)
    out = vertex_cache_order(m.positions, tri)
    assert sorted(map(tuple, out.tolist())) == sorted(map(tuple, tri.tolist()))  # same triangles, same winding
    assert vsplit_shaded(out) <= vsplit_shaded(tri)
    assert vsplit_shaded(out) < 0.8 * vsplit_shaded(tri)  # the procedural tubes' strips gain a lot
    p = np.zeros((3, 3))
    assert vertex_cache_order(p, np.array([[0, 1, 2]])).shape == (1, 3)
    assert morton_order(p, np.zeros((0, 3), np.int64)).size == 0
    same = np.array([[0, 1, 2], [0, 2, 1]])  # coincident centroids: the stable sort keeps their order
    assert np.array_equal(morton_order(np.eye(3), same), [0, 1])


def test_reordered_draw_keeps_the_image(gl_ctx):
    rep = build_rep(humanoid(4000, seed=9), key="order:h")
    st = CrowdState.empty(6)
    st.position[:, 0] = np.arange(6) * 0.8 - 2.0
    st.heading[:] = np.linspace(0, 5, 6)
    st.anim_time[:] = 0.21 * np.arange(6)
    cam = Camera.look_at((0.3, 1.7, 4.2), (0.0, 0.9, 0.0), fov_y=50.0, near=0.1, far=50.0)
    size = (256, 160)
    images = []
    for reorder in (True, False):
        with Renderer(size, ctx=gl_ctx, debug=True) as r:
            r.reorder_triangles = reorder
            r.upload(rep)
            r.draw(NoLodSelector([rep]).select(st, cam, size))
            images.append(r.read_pixels().astype(np.int64))
    a, b = images
    assert np.any(a != a[0, 0])
    assert (np.abs(a - b).max(axis=2) > 1).mean() <= 1e-3  # only equal-depth ties may differ
