"""sim.routing.corners: visibility (bucketed against every edge), the wedge test, corner distances against an
independent visibility graph, and the node vias against their plain reference."""
import numpy as np
import pytest
from routing_testutil import U_BOUNDS, U_BOXES, U_GOAL, ExactPaths

import sim.routing.corners as cn
from sim.routing.geometry import Walkable
from sim.routing.router import Router


@pytest.fixture(scope="module")
def utrap():
    w = Walkable.from_config({"bounds": U_BOUNDS}, {"boxes": U_BOXES})
    return w, Router(w, 0.25, cell=0.25)


def test_visible_equals_brute_force(utrap):
    _, r = utrap
    rings = cn.rings_of(r.free_space)
    rng = np.random.default_rng(5)
    a = rng.uniform((-15, -10), (16, 10), (3000, 2))
    b = rng.uniform((-15, -10), (16, 10), (3000, 2))
    ba = r.buckets.args()
    got = [cn.visible(p[0], p[1], q[0], q[1], *ba) for p, q in zip(a, b)]
    ref = [cn.visible_numpy(p, q, rings) for p, q in zip(a, b)]
    assert got == ref and 0 < sum(got) < len(got)


def test_wedge_rejects_a_segment_inside_a_wall(utrap):
    _, r = utrap
    C = r.corners
    # the inner end of the north arm's south face and the outer back corner: no edge is crossed properly, the
    # segment runs inside the wall from end to end
    a = int(np.argmin(np.hypot(C[:, 0] + 4.0, C[:, 1] - 3.6)))
    b = int(np.argmin(np.hypot(C[:, 0] - 4.4, C[:, 1] - 4.15)))
    assert np.hypot(*(C[a] - (-4.0, 3.6))) < 1e-6 and np.hypot(*(C[b] - (4.4, 4.15))) < 1e-6
    d = C[b] - C[a]
    assert cn.visible(C[a, 0], C[a, 1], C[b, 0], C[b, 1], *r.buckets.args())  # the edge test alone lets it pass
    assert not cn.wedge_ok(r.wedges, a, d[0], d[1]) or not cn.wedge_ok(r.wedges, b, -d[0], -d[1])
    assert cn.wedge_ok(r.wedges, a, -1.0, -0.2)  # leaving the arm's end into the open


def test_corner_distances_are_exact(utrap):
    w, r = utrap
    gid = r.goal(("point", U_GOAL))
    D = r._D[gid]
    ex = ExactPaths(w.area, 0.25 - 1e-6)
    for c in range(0, r.corners.shape[0], 3):
        assert D[c] == pytest.approx(ex.length(r.corners[c], U_GOAL), rel=2e-3), c


def test_via_kernel_equals_reference(utrap):
    w, _ = utrap
    r = Router(w, 0.25, cell=0.5)  # a coarse grid keeps the reference quick
    for shape in (("point", U_GOAL), ("line", ((9.0, -1.0), (9.0, 1.0))),
                  ("polygon", [(12.0, 6.0), (14.0, 6.0), (14.0, 8.0), (12.0, 8.0)])):
        gid = r.goal(shape)
        from sim.routing.field import march_goal

        T, _ = march_goal(r.grid, r.free, r.band, r.shapes[gid], r.clearance, r.order)
        ok = np.nonzero(r.free.ravel() & np.isfinite(T))[0]
        order = ok[np.argsort(T[ok], kind="stable")]
        start, items = cn.node_seeds(r.grid, r.free, r.corners)
        kid_start, kids = cn.children_of(r._next[gid])
        gseg, area = cn.goal_segments(r.shapes[gid])
        ref = cn.via_numpy(order, r.grid.nx, r.grid.x0, r.grid.z0, r.grid.h, r.corners, r.wedges, r._D[gid],
                           kid_start, kids, start, items, gseg, area, cn.rings_of(r.free_space), r.grid.nodes)
        got = r._vias[gid].ravel().copy()
        got[r.band[0]] = cn.VIA_NONE  # the band copies its nearest free node's via after the kernel
        assert np.array_equal(got, ref)
        assert (got >= 0).sum() > 50 and (got == cn.VIA_GOAL).sum() > 50


@pytest.mark.parametrize("shape", [("point", (1.0, 2.0)), ("line", ((0.0, 0.0), (3.0, 1.0))),
                                   ("polygon", [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (1.0, 0.5), (0.0, 2.0)])])
def test_goal_nearest_equals_shapely(shape):
    seg, area = cn.goal_segments(shape)
    rng = np.random.default_rng(1)
    for p in rng.uniform(-1.0, 3.0, (200, 2)):
        got = cn.goal_nearest(p[0], p[1], seg, 0, seg.shape[0], area)
        ref = cn.goal_nearest_numpy(p, seg, area)
        assert np.allclose(got, ref, atol=1e-12), (p, got, ref)


def test_dense_dijkstra_equals_heap_reference(utrap):
    _, r = utrap
    vis = cn.visibility_matrix(r.corners, r.wedges, r.buckets)
    rng = np.random.default_rng(3)
    gd = np.where(rng.random(r.corners.shape[0]) < 0.3, rng.uniform(1, 20, r.corners.shape[0]), np.inf)
    D, nxt = cn.corner_distances(r.corners, vis, gd)
    D2, nxt2 = cn.corner_distances_numpy(r.corners, vis, gd)
    np.testing.assert_allclose(D, D2, rtol=1e-12)
    assert np.array_equal(nxt, nxt2)
