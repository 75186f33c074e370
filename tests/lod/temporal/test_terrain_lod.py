"""View-dependent bisection terrain (lod.temporal.terrain)."""
import numpy as np
import pytest

from lod.temporal.bisection import BisectionForest
from lod.full.reps import build_static_rep
from lod.temporal.terrain import (
    TerrainHierarchy, _collect_leaves, _node_errors, collect_leaves_reference, node_errors_reference,
)
from lod.view import Camera
from sim.terrain import Terrain, fbm_value_noise

SIZE = (320, 240)


@pytest.fixture(scope="module")
def small():
    h = fbm_value_noise(33, 33, seed=3, octaves=4) * 20.0
    return TerrainHierarchy(Terrain(h, (128.0, 128.0), (-64.0, 0.0, -64.0)))


def cam_over(dist=90.0, height=35.0):
    return Camera.look_at([0.0, height, dist], [0.0, 0.0, 0.0], fov_y=50.0, near=0.5, far=1000.0)


def hanging(h, tris):
    """Leaf edges whose grid midpoint is a vertex of the section (a hanging node)."""
    used = np.zeros(h.n_vertices, bool)
    used[tris.ravel()] = True
    n = h.n_side
    bad = 0
    for t in tris:
        for k in range(3):
            a, b = t[k], t[(k + 1) % 3]
            xa, za, xb, zb = a % n, a // n, b % n, b // n
            if (xa + xb) % 2 == 0 and (za + zb) % 2 == 0:
                m = ((za + zb) // 2) * n + (xa + xb) // 2
                bad += int(used[m])
    return bad


def test_node_errors_kernel_matches_reference(small):
    ref = node_errors_reference(small.tri, small.terrain.heights, small.first_leaf)
    got = _node_errors(small.tri, small.terrain.heights, small.first_leaf)
    np.testing.assert_allclose(got, ref, atol=1e-9)
    assert ref[2:small.first_leaf].max() > 1.0


def test_collect_leaves_kernel_matches_reference(small):
    act = small.active_vertices(cam_over(), SIZE, tau=0.7)
    got = np.sort(_collect_leaves(small.mid, act, small.first_leaf))
    ref = collect_leaves_reference(small.mid, act, small.first_leaf)
    np.testing.assert_array_equal(got, ref)
    assert 10 < got.size < small.n_full_triangles


def test_full_depth_is_the_grid_and_root_is_two_triangles(small):
    allon = np.ones(small.n_vertices, bool)
    full = small.section(allon)
    assert full.leaves.size == small.n_full_triangles
    # the finest level is the grid with alternating (4-8) diagonals: every grid cell is split in two
    n = small.n_side
    xs, zs = full.triangles % n, full.triangles // n
    assert np.all(xs.max(1) - xs.min(1) == 1) and np.all(zs.max(1) - zs.min(1) == 1)
    cells = (zs.min(1) * n + xs.min(1))
    assert np.all(np.bincount(cells, minlength=n * n)[(np.arange(n * n) % n < n - 1) & (np.arange(n * n) // n < n - 1)] == 2)
    none = small.section(np.zeros(small.n_vertices, bool))
    assert none.leaves.size == 2


def test_selection_is_dependency_closed_conforming_and_equals_definition1(small):
    cam = cam_over()
    sel = small.select(cam, SIZE, tau=0.7)
    assert hanging(small, sel.triangles) == 0
    # Definition 1 on a generic forest, marking each leaf whose midpoint is active
    n = small.n_side
    s = n - 1
    xz = np.array([[0, 0], [s, 0], [s, s], [0, s]], np.float64)
    f = BisectionForest(xz, np.array([[0, 2, 1], [2, 0, 3]]), [0, 0])

    def pred(forest, lv):
        m = forest.verts[forest.tri[lv, 0]] * 0.5 + forest.verts[forest.tri[lv, 1]] * 0.5
        return sel.active[(m[:, 1] * n + m[:, 0]).astype(np.int64)]

    f.refine_where(pred, max_level=2 * small.k)
    gid = np.round(f.verts[: f.n_verts, 1]).astype(np.int64) * n + np.round(f.verts[: f.n_verts, 0]).astype(np.int64)
    ref = {tuple(t) for t in gid[f.leaf_triangles()]}
    assert ref == {tuple(t) for t in sel.triangles}
    # the flagged section is closed: no extra closure bisections were needed
    g = BisectionForest(xz, np.array([[0, 2, 1], [2, 0, 3]]), [0, 0])
    for _ in range(2 * small.k):
        lv = g.leaves()
        mk = lv[pred(g, lv) & (g.level[lv] < 2 * small.k)]
        for i in mk:
            g.bisect(int(i))
    assert g.hanging_leaves().size == 0


@pytest.mark.parametrize("tau", [0.5, 2.0])
def test_screen_space_error_bounded_at_sampled_points(small, tau):
    cam = cam_over(70.0, 25.0)
    sel = small.select(cam, SIZE, tau=tau)
    full = small.section(np.ones(small.n_vertices, bool))
    rng = np.random.default_rng(0)
    x = rng.uniform(-64, 64, 400)
    z = rng.uniform(-64, 64, 400)
    y = small.positions[:, 1]
    h_lod = small.surface_height(sel.leaves, y, x, z)
    h_full = small.surface_height(full.leaves, y, x, z)
    p = np.stack([x, h_full, z], 1)
    q = np.stack([x, h_lod, z], 1)
    px, d = cam.project(p, SIZE, return_depth=True)
    qx = cam.project(q, SIZE)
    inside = (d > cam.near) & (px[:, 0] >= 0) & (px[:, 0] <= SIZE[0]) & (px[:, 1] >= 0) & (px[:, 1] <= SIZE[1])
    assert inside.sum() > 100
    pix = np.linalg.norm(px - qx, axis=1)[inside]
    assert pix.max() <= tau * 1.01 + 1e-6
    assert pix.max() > 0.2 * tau  # the LOD does use its error budget
    assert sel.leaves.size < 0.9 * small.n_full_triangles


def test_triangle_count_drops_with_distance(small):
    counts = [small.select(Camera.look_at([0.0, 20.0 + 0.3 * d, d], [0.0, 0.0, 0.0], near=0.5, far=5000.0),
                           SIZE, tau=1.0, cull=False).leaves.size for d in (60.0, 150.0, 400.0, 1200.0)]
    assert all(a > b for a, b in zip(counts, counts[1:])), counts
    # within one view, triangles far away are larger than near ones
    cam = Camera.look_at([0.0, 25.0, 60.0], [0.0, 0.0, -20.0], near=0.5)
    sel = small.select(cam, SIZE, tau=3.0, cull=False)
    p = small.positions[sel.triangles]
    area = 0.5 * np.abs(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])[:, 1])
    dist = np.linalg.norm(p.mean(1) - cam.position, axis=1)
    near_a = area[dist < np.percentile(dist, 20)].mean()
    far_a = area[dist > np.percentile(dist, 80)].mean()
    assert far_a > 1.5 * near_a


def test_culling_drops_triangles_outside_frustum(small):
    cam = Camera.look_at([0.0, 10.0, 0.0], [50.0, 0.0, 0.0], near=0.5)
    a = small.select(cam, SIZE, tau=1.0, cull=True).leaves.size
    b = small.select(cam, SIZE, tau=1.0, cull=False).leaves.size
    assert a < b


def test_mesh_output_is_drawable_static_rep(small):
    sel = small.select(cam_over(), SIZE, tau=1.0)
    m = small.mesh(sel)
    assert m.positions.dtype == np.float32 and m.indices.dtype == np.uint32
    assert np.isfinite(m.positions).all() and np.isfinite(m.normals).all()
    assert m.indices.shape == (sel.leaves.size, 3) and m.indices.max() < m.n_vertices
    p = m.positions.astype(np.float64)[m.indices]
    fn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert (fn[:, 1] > 0).all()  # counter-clockwise seen from +Y, like Terrain.mesh
    rep = build_static_rep(m, "terrain")
    assert rep.indices.shape[0] == sel.leaves.size


def test_flat_and_resampled_terrains():
    flat = TerrainHierarchy(Terrain(np.zeros((9, 9)), (10.0, 10.0), (-5.0, 0.0, -5.0)))
    assert flat.select(cam_over(20.0, 5.0), SIZE, tau=0.1).leaves.size == 2
    odd = TerrainHierarchy(Terrain(np.random.default_rng(1).random((20, 13)) * 3.0, (10.0, 20.0), (0.0, 0.0, 0.0)))
    assert odd.n_side == 33
    assert np.isfinite(odd.positions).all()
    np.testing.assert_allclose(odd.positions[:, 1].max(), odd.terrain.heights.max())
    with pytest.raises(ValueError):
        flat.select(cam_over(), SIZE, tau=0.0)
    with pytest.raises(ValueError):
        flat.select(cam_over(), SIZE, tau=float("nan"))


@pytest.mark.parametrize("cull", [True, False])
def test_active_and_height_kernels_match_references(small, cull):
    for cam in (cam_over(), cam_over(20.0, 3.0), Camera.look_at([0.0, 10.0, 0.0], [50.0, 0.0, 0.0], near=0.5)):
        got = small.active_vertices(cam, SIZE, 0.8, cull)
        ref = small.active_vertices_reference(cam, SIZE, 0.8, cull)
        np.testing.assert_array_equal(got, ref)
        assert 0 < got.sum() < small.n_vertices
        np.testing.assert_allclose(small.interpolated_heights(got), small.interpolated_heights_reference(got),
                                   atol=1e-12)
        # inactive vertices sit on the section's surface, active ones keep their true height
        y = small.interpolated_heights(got)
        np.testing.assert_array_equal(y[got], small.positions[got, 1])
