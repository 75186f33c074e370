"""Rivara/Bänsch bisection (lod.temporal.bisection): conformity, Fig. 2 inheritance, coarsening."""
import numpy as np
import pytest

from lod.temporal.bisection import BisectionForest, triangle_angles


def cross2(v, t):
    """(T,) float64 twice the signed areas of 2-D triangles."""
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    return (b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]


def conforming(verts, tris):
    """Independent check: every interior edge has exactly two triangles, no
    vertex of the mesh lies strictly inside a triangle edge (hanging node)."""
    tris = np.asarray(tris)
    used = np.unique(tris)
    p = verts[used]
    edges = {}
    for t in tris:
        for k in range(3):
            a, b = int(t[k]), int(t[(k + 1) % 3])
            e = (min(a, b), max(a, b))
            edges[e] = edges.get(e, 0) + 1
    if max(edges.values()) > 2:
        return False
    for (a, b) in edges:
        pa, pb = verts[a], verts[b]
        d = pb - pa
        s = ((p - pa) @ d) / (d @ d)
        q = pa + s[:, None] * d
        on = (np.linalg.norm(p - q, axis=1) < 1e-12) & (s > 1e-9) & (s < 1 - 1e-9)
        if on.any():
            return False
    return True


def square(n=2):
    """n x n grid of squares, each split along a diagonal: a conforming root complex."""
    x, y = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    v = np.stack([x.ravel(), y.ravel()], 1)
    k = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = k[:-1, :-1].ravel(), k[:-1, 1:].ravel(), k[1:, :-1].ravel(), k[1:, 1:].ravel()
    t = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    return v, t


def random_complex(seed):
    rng = np.random.default_rng(seed)
    v, t = square(3)
    v = v.copy()
    inner = (v[:, 0] > 0) & (v[:, 0] < 1) & (v[:, 1] > 0) & (v[:, 1] < 1)
    v[inner] += rng.uniform(-0.08, 0.08, (inner.sum(), 2))
    return v, t


def test_root_refinement_edge_is_longest_and_orientation_kept():
    v, t = random_complex(1)
    f = BisectionForest(v, t)
    tri = f.tri[: f.n_roots]
    p = v[tri]
    lens = np.linalg.norm(np.roll(p, -1, axis=1) - p, axis=2)
    assert np.all(np.argmax(lens, axis=1) == 0)
    area0 = cross2(v, t)
    f.refine(range(f.n_roots))
    lt = f.leaf_triangles()
    vv = f.verts[: f.n_verts]
    area = cross2(vv, lt)
    assert np.all(np.sign(area) == np.sign(area0[0]))


def test_children_inherit_refinement_edges_as_fig2():
    f = BisectionForest(np.array([[0, 0], [2, 0], [1, 1.0]]), np.array([[0, 1, 2]]), [0])
    ch = f.bisect(0)
    m = f.refinement_midpoint(0)
    assert np.allclose(f.verts[m], [1, 0])
    # children (v2, v0, m) and (v1, v2, m): refinement edges are the parent's other edges,
    # the new vertex is the newest vertex (apex) of both
    assert tuple(f.tri[ch]) == (2, 0, m) and tuple(f.tri[ch + 1]) == (1, 2, m)
    # grandchildren: the next bisection is at the old edge, newest vertex again apex
    g = f.bisect(ch)
    m2 = f.refinement_midpoint(ch)
    assert np.allclose(f.verts[m2], [0.5, 0.5])
    assert tuple(f.tri[g]) == (m, 2, m2) and tuple(f.tri[g + 1]) == (0, m, m2)


def test_single_refine_closure_makes_conforming():
    v, t = square(2)
    f = BisectionForest(v, t)
    f.refine([0])
    assert conforming(f.verts[: f.n_verts], f.leaf_triangles())
    assert f.hanging_leaves().size == 0
    # bisecting without closure leaves a hanging node the checker detects
    g = BisectionForest(v, t)
    leaf = g.leaves()[0]
    ch = g.bisect(leaf)
    g.bisect(ch)
    assert not conforming(g.verts[: g.n_verts], g.leaf_triangles()) or g.hanging_leaves().size == 0
    assert g.hanging_leaves().size > 0


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_random_refine_coarsen_sequences_stay_conforming_and_angles_bounded(seed):
    rng = np.random.default_rng(seed)
    v, t = random_complex(seed)
    f = BisectionForest(v, t)
    min0 = triangle_angles(v, t).min()
    for step in range(14):
        lv = f.leaves()
        if rng.random() < 0.65:
            f.refine(rng.choice(lv, size=max(1, lv.size // 6), replace=False))
        else:
            inner = np.flatnonzero(f.active[: f.n_nodes] & ~f.leaf[: f.n_nodes])
            if inner.size:
                f.coarsen(rng.choice(inner, size=max(1, inner.size // 3), replace=False))
        vv = f.verts[: f.n_verts]
        lt = f.leaf_triangles()
        assert conforming(vv, lt), f"step {step}"
        assert f.hanging_leaves().size == 0
        assert triangle_angles(vv, lt).min() >= 0.5 * min0 - 1e-12
        # leaves tile the domain: area preserved
        area = 0.5 * np.abs(cross2(vv, lt)).sum()
        assert area == pytest.approx(1.0, abs=1e-12)
    assert f.n_bisections > 20


def test_refine_then_coarsen_returns_root_complex():
    v, t = random_complex(7)
    f = BisectionForest(v, t)
    roots = {tuple(r) for r in f.leaf_triangles()}
    for _ in range(5):
        f.refine(f.leaves()[::3])
    assert f.leaves().size > 3 * len(roots)
    f.coarsen_all()
    assert {tuple(r) for r in f.leaf_triangles()} == roots
    assert np.all(f.vuse[f.n_root_verts: f.n_verts] == 0)
    # re-refining reuses the persistent children and vertices
    nn, nv = f.n_nodes, f.n_verts
    f.refine([0])
    f.coarsen_all()
    f.refine([0])
    assert f.n_verts == nv and f.n_nodes == nn


def test_coarsen_refuses_when_it_would_break_conformity():
    v, t = square(2)
    f = BisectionForest(v, t)
    f.refine([0])
    f.refine(f.leaves())  # deeper everywhere
    f.refine([f.leaves()[0]])
    # the root's bisection cannot be undone while its children are bisected
    assert not f.can_coarsen(0)
    assert f.coarsen([0]) == 0
    assert conforming(f.verts[: f.n_verts], f.leaf_triangles())


def test_degenerate_inputs():
    with pytest.raises(ValueError):
        BisectionForest(np.array([[0, 0], [1, np.nan], [0, 1.0]]), np.array([[0, 1, 2]]))
    with pytest.raises(ValueError):
        BisectionForest(np.zeros((3, 2)), np.array([[0, 1, 5]]))
    f = BisectionForest(np.zeros((0, 2)), np.zeros((0, 3), int))
    assert f.leaves().size == 0 and f.refine([]) == 0 and f.coarsen_all() == 0
    g = BisectionForest(np.array([[0, 0], [1, 0], [0, 1.0]]), np.array([[0, 1, 2]]))
    assert g.refine([99, -1]) == 0
    assert g.path(0) == (0,)
