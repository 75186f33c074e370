"""Multi-pose quadric error simplification (lod/simplify/collapse.py, VDR-AM §4.3 after DR05)."""
import numpy as np
import pytest

from lod.clusters import poses
from lod.simplify import collapse as qem
from lod.simplify import distance as qem_distance
from lod.simplify import kernels as qem_kernels
from lod.simplify import quadrics as qem_quadrics
from lod.clusters.dag import skin_poses
from sim.procedural import humanoid


def grid(n=8, z=None):
    """(n+1)^2 vertex planar grid in the XY plane, 2 n^2 triangles (open border)."""
    xs = np.linspace(0, 1, n + 1)
    P = np.array([[x, y, 0.0 if z is None else z(x, y)] for y in xs for x in xs])
    t = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            t += [[a, a + 1, a + n + 2], [a, a + n + 2, a + n + 1]]
    return P, np.array(t)


def sphere_mesh(n=12):
    """A closed UV sphere."""
    th = np.linspace(0, np.pi, n + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, 2 * n, endpoint=False)
    P = [[0, 1, 0]] + [[np.sin(a) * np.cos(b), np.cos(a), np.sin(a) * np.sin(b)] for a in th for b in ph] + [[0, -1, 0]]
    m = 2 * n
    t = [[0, 1 + (k + 1) % m, 1 + k] for k in range(m)]
    for r in range(len(th) - 1):
        for k in range(m):
            a, b = 1 + r * m + k, 1 + r * m + (k + 1) % m
            t += [[a, b, b + m], [a, b + m, a + m]]
    last = 1 + (len(th) - 1) * m
    t += [[last + k, last + (k + 1) % m, len(P) - 1] for k in range(m)]
    return np.array(P, float), np.array(t)


def open_edges(t):
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), 1)
    _, cnt = np.unique(e, axis=0, return_counts=True)
    return int(np.count_nonzero(cnt != 2))


def test_quadrics_kernel_matches_numpy_reference():
    P, t = sphere_mesh(6)
    X = np.stack([P, P * 1.5 + 0.3])
    t = np.vstack([t, [[0, 0, 1]]])  # a degenerate triangle adds nothing
    np.testing.assert_allclose(qem_quadrics.plane_quadrics(X, t), qem_quadrics.plane_quadrics_numpy(X, t), atol=1e-12)
    Q = qem_quadrics.plane_quadrics_numpy(X, t)
    # every vertex lies on its own triangles' planes: zero error at its position, in every pose
    np.testing.assert_allclose(qem_quadrics.quadric_eval_numpy(Q, X), 0.0, atol=1e-12)


def test_planar_grid_simplifies_at_zero_error_and_keeps_its_border():
    P, t = grid(8)
    out, remap, err = qem.simplify(P[None], t, 20)
    assert out.shape[0] <= 20 or out.shape[0] < t.shape[0]
    assert err == pytest.approx(0.0, abs=1e-9)
    border = (P[:, 0] % 1 == 0) | (P[:, 1] % 1 == 0)
    assert np.all(remap[border] == np.nonzero(border)[0])  # open-border vertices never move
    assert np.all(np.isin(remap, np.unique(out)) | ~np.isin(np.arange(len(P)), np.unique(t)))
    # the simplified grid still covers the unit square (area preserved)
    a = np.cross(P[out[:, 1]] - P[out[:, 0]], P[out[:, 2]] - P[out[:, 0]])[:, 2]
    assert np.all(a > 0) and a.sum() / 2 == pytest.approx(1.0)


def test_locked_vertices_never_move():
    P, t = sphere_mesh(10)
    lock = P[:, 1] > 0.3
    out, remap, _ = qem.simplify(P, t, 30, locked_vertices=lock)
    assert np.all(remap[lock] == np.nonzero(lock)[0])
    assert np.all(np.isin(np.nonzero(lock)[0], out))
    # edges between locked vertices whose triangles were all locked-only stay untouched
    full = np.all(lock[t], axis=1)
    kept = {tuple(sorted(x)) for x in out.tolist()}
    assert all(tuple(sorted(x)) in kept for x in t[full].tolist())


def test_closed_mesh_stays_closed_and_meets_target():
    P, t = sphere_mesh(12)
    X = np.stack([P, P * [1.3, 0.8, 1.0]])
    out, remap, err = qem.simplify(X, t, t.shape[0] // 4)
    assert out.shape[0] <= t.shape[0] // 4
    assert open_edges(out) == 0
    assert 0 < err < 0.5
    assert np.all(remap[remap] == remap)  # remap points at survivors
    d = qem_distance.vertex_surface_distance(X, t, out)
    assert d.shape == (2, len(P)) and d.max() < 0.5


def test_degenerate_inputs():
    P, t = grid(2)
    out, remap, err = qem.simplify(P, t, 100)  # target above T: unchanged
    assert np.array_equal(out, t) and err == 0.0 and np.array_equal(remap, np.arange(len(P)))
    out, remap, err = qem.simplify(P, np.zeros((0, 3), int), 0)
    assert out.shape == (0, 3) and err == 0.0
    dup = np.array([[0, 0, 1], [0, 1, 2]])
    out, _, _ = qem.simplify(np.eye(3), dup, 5)
    assert out.tolist() == [[0, 1, 2]]  # degenerate triangles are dropped
    with pytest.raises(ValueError, match="NaN"):
        qem.simplify(np.full((3, 3), np.nan), [[0, 1, 2]], 0)
    with pytest.raises(ValueError, match="indices"):
        qem.simplify(np.eye(3), [[0, 1, 5]], 0)
    with pytest.raises(ValueError, match="locked_vertices"):
        qem.simplify(np.eye(3), [[0, 1, 2]], 0, locked_vertices=np.zeros(2, bool))
    with pytest.raises(ValueError, match="target"):
        qem.simplify(np.eye(3), [[0, 1, 2]], -1)


def test_collapse_distance_bounds_the_surface_distance():
    P, t = sphere_mesh(10)
    out, remap, _ = qem.simplify(P, t, 60)
    verts = np.unique(t)
    cd = qem_distance.collapse_distance(P[None], out, verts, remap)
    true = qem_distance.vertex_surface_distance(P[None], t, out).max()
    assert true <= cd + 1e-12 and cd > 0


def test_representative_pose_error_within_5_percent_of_all_poses():
    """VDR-AM §6: simplifying with the selected poses costs <= 5 % RMS distance over the 35-pose walk."""
    c = humanoid(1500, 0)
    clip = c.clip("walk")
    times = poses.sample_times(clip, 35)
    X = skin_poses(c.mesh, clip.skinning_matrices(c.skeleton, times))
    reps, _ = poses.select_poses(poses.classical_mds(poses.pose_features(c.skeleton, clip, times)),
                                 poses.pose_distance(c))
    assert 5 <= len(reps) <= 12
    for target in (750, 375):
        rms = []
        for sel in (reps, np.arange(35)):
            out, _, _ = qem.simplify(X[sel], c.mesh.indices, target)
            d = qem_distance.vertex_surface_distance(X, c.mesh.indices, out)
            rms.append(np.sqrt(np.mean(d ** 2)))
        assert rms[0] <= 1.05 * rms[1], (target, rms)


def test_collapse_kernel_matches_python_reference():
    """Same collapses as the plain-Python reference on a noisy two-pose sphere (distinct costs)."""
    rng = np.random.default_rng(5)
    P, t = sphere_mesh(8)
    P = P * (1 + 0.05 * rng.standard_normal((len(P), 1)))
    X = np.ascontiguousarray(np.stack([P, P * [1.2, 0.9, 1.0] + 0.1 * P[:, [1, 2, 0]] ** 2]))
    lock = np.zeros(len(P), bool)
    lock[rng.choice(len(P), 10, replace=False)] = True
    for target in (150, 60, 20):
        Qa = qem_quadrics.plane_quadrics(X, t)
        Qb = Qa.copy()
        ta = t.astype(np.int64).copy()
        alive_a, remap_a, err_a, live_a = qem_kernels._simplify_kernel(X, ta, lock, Qa, target, 0.0)
        alive_b, remap_b, err_b, live_b = qem.simplify_reference(X, t, target, lock, Qb, 0.0)
        assert live_a == live_b and np.array_equal(alive_a, alive_b)
        assert np.array_equal(remap_a, remap_b)
        assert err_a == pytest.approx(err_b, rel=1e-9)
        np.testing.assert_allclose(Qa, Qb, rtol=1e-9, atol=1e-12)


def _bumpy_sphere_case(n=5):
    P, t = sphere_mesh(n)
    X = np.stack([P, P * [1.0, 1.3, 0.9]])  # two "poses"
    simp, remap, _ = qem.simplify(X, t, len(t) // 3)
    return X, t, simp, remap


def test_cluster_hausdorff_matches_numpy_reference():
    X, t, simp, remap = _bumpy_sphere_case()
    rv = np.unique(t)
    mask = np.ones(len(t), bool)
    f, b = qem_distance.cluster_hausdorff(X, simp, rv, remap, t, mask)
    fr, br = qem_distance.cluster_hausdorff_numpy(X, simp, rv, t, mask)
    assert f == pytest.approx(fr, rel=1e-9, abs=1e-12)
    assert fr > 1e-3  # really simplified
    assert b >= br - 1e-12 and b <= 2.0 * br + 1e-9  # conservative, not loose
    # unsimplified: zero both ways
    f0, b0 = qem_distance.cluster_hausdorff(X, t, rv, np.arange(X.shape[1]), t, mask)
    assert f0 == 0.0 and b0 == pytest.approx(0.0, abs=1e-12)


def test_cluster_hausdorff_degenerate_inputs():
    X, t, simp, remap = _bumpy_sphere_case()
    rv = np.unique(t)
    mask = np.ones(len(t), bool)
    assert qem_distance.cluster_hausdorff(X, np.zeros((0, 3), int), rv, remap, t, mask)[0] == np.inf
    assert qem_distance.cluster_hausdorff(X, simp, np.zeros(0, int), remap, t, mask)[0] == 0.0
    with pytest.raises(ValueError, match="region_mask"):
        qem_distance.cluster_hausdorff(X, simp, rv, remap, t, mask[:-1])
    with pytest.raises(ValueError, match="simplified"):
        qem_distance.cluster_hausdorff(X, simp + 10 ** 6, rv, remap, t, mask)


def test_cluster_hausdorff_normal_compatible():
    """The normal-compatible forward distance is never below the plain one, is 0 for an
    unsimplified mesh, and charges a vertex no simplified triangle faces (a sphere replaced by
    its upper half: the lower half's vertices face away from every kept triangle)."""
    X, t, simp, remap = _bumpy_sphere_case()
    rv = np.unique(t)
    mask = np.ones(len(t), bool)
    f, b = qem_distance.cluster_hausdorff(X, simp, rv, remap, t, mask)
    fn, bn = qem_distance.cluster_hausdorff(X, simp, rv, remap, t, mask, normal_cos=qem_distance.HAUSDORFF_NORMAL_COS)
    assert fn >= f - 1e-12 and bn == pytest.approx(b)
    f0, _ = qem_distance.cluster_hausdorff(X, t, rv, np.arange(X.shape[1]), t, mask, normal_cos=qem_distance.HAUSDORFF_NORMAL_COS)
    assert f0 == 0.0
    c = X[0][t].mean(axis=1)
    top = t[c[:, 2] > 0.2]
    plain, _ = qem_distance.cluster_hausdorff(X, top, rv, np.arange(X.shape[1]), t, mask)
    compat, _ = qem_distance.cluster_hausdorff(X, top, rv, np.arange(X.shape[1]), t, mask,
                                      normal_cos=qem_distance.HAUSDORFF_NORMAL_COS)
    assert compat > plain + 0.1
    n = qem_distance.vertex_normals(X, t)
    assert np.allclose(np.linalg.norm(n[:, rv], axis=2), 1.0)


def test_cluster_hausdorff_vertex_without_facing_measures_plain_distance():
    """A vertex whose normals cancel (a sheet drawn from both sides on shared vertices) or that only zero-area
    triangles touch has no facing: it is compatible with every triangle (the plain distance). Before, no
    triangle faced it and it was charged the distance to the farthest point of the cluster."""
    P, t = grid(4)
    X = np.stack([P, P * [1.0, 1.2, 1.0]])
    n = len(P)
    X = np.concatenate([X, X[:, :1] + [0.5, 0.5, 0.0]], axis=1)  # a vertex on a zero-area triangle only
    two = np.vstack([t, t[:, ::-1], [[0, 1, n]]])                # both sides + the sliver (0, 1, n) ...
    X[:, n] = 0.5 * (X[:, 0] + X[:, 1])                          # ... with n on the edge 0-1: zero area
    rv = np.unique(two)
    mask = np.ones(len(two), bool)
    ident = np.arange(X.shape[1])
    cos = qem_distance.HAUSDORFF_NORMAL_COS
    f0, _ = qem_distance.cluster_hausdorff(X, two, rv, ident, two, mask, normal_cos=cos)
    assert f0 == 0.0  # unsimplified: zero (it was the sheet's diagonal)
    half = two[:len(t) // 2]  # half the sheet, one side: the plain distance to it, not the farthest point
    plain, _ = qem_distance.cluster_hausdorff(X, half, rv, ident, two, mask)
    compat, _ = qem_distance.cluster_hausdorff(X, half, rv, ident, two, mask, normal_cos=cos)
    assert compat == pytest.approx(plain) and plain > 0.1


@pytest.mark.parametrize("seed", range(6))
def test_simplify_accounts_for_every_vertex_of_its_drawable_input(seed):
    """What the cluster hierarchy's collapse tracking relies on: every vertex of the drawable input triangles
    (no repeated index, ``drawable_triangles``) is in the output or collapsed onto a vertex that is, on inputs
    with duplicate, two-sided, non-manifold and zero-area triangles."""
    rng = np.random.default_rng(seed)
    P, t = sphere_mesh(6)
    n = len(P)
    P = np.vstack([P, P[:4], P[:2] + 0.3])                       # coincident copies, fin tips
    extra = [[0, n, 1], [1, n + 1, 2], [2, 3, n + 2],            # zero-area on coincident vertices
             [0, 0, n + 3], [5, 5, n + 4], [1, 2, n + 4],        # repeated index, a fin, a two-sided pair
             [t[3, 0], t[3, 1], n + 5], [t[3, 1], t[3, 0], n + 5]]
    t = np.vstack([t, t[rng.integers(0, len(t), 5)], t[rng.integers(0, len(t), 5), ::-1], extra])
    X = np.stack([P, P * [1.0, 1.3, 0.9]])
    lock = rng.random(len(P)) < 0.1
    out, remap, _ = qem.simplify(X, t, int(rng.integers(0, len(t) // 2)), locked_vertices=lock)
    kept = np.zeros(len(P), bool)
    kept[out.reshape(-1)] = True
    used = np.unique(qem.drawable_triangles(t))
    assert kept[remap[used]].all()
    assert (remap[lock] == np.flatnonzero(lock)).all()  # locked vertices never move


def test_vertex_normals_kernel_matches_numpy_reference():
    """Unit normals, and 0 for unused vertices, zero-area-only vertices and cancelling two-sided sheets."""
    P, t = grid(3)
    X = np.stack([P, P * [1.0, 1.5, 1.0] + [0, 0, 0.2]])
    X = np.concatenate([X, X[:, :2], X[:, 5:6] + 1.0], axis=1)   # two coincident copies, one unused vertex
    n = P.shape[0]
    tris = np.vstack([t, t[:4, ::-1], [[n, n + 1, 0]]])  # 4 triangles both sides, one zero-area triangle
    got = qem_distance.vertex_normals(X, tris)
    ref = qem_distance.vertex_normals_numpy(X, tris)
    np.testing.assert_allclose(got, ref, atol=1e-12)
    ln = np.linalg.norm(got, axis=2)
    assert (ln[:, [n, n + 1, n + 2]] == 0).all()  # zero-area only, unused
    both = np.setdiff1d(np.unique(t[:4]), np.unique(t[4:]))  # vertices only on the two-sided triangles
    assert both.size and (ln[:, both] == 0).all()
    assert np.allclose(ln[:, np.unique(t[4:])], 1.0)
