"""§3.2 traversal: numba kernel vs reference, exclusivity, culling, camera inside, completeness."""
import numpy as np
import pytest

from lod.points.octree import build_hierarchy
from lod.points.traverse import traverse, traverse_reference, viewport_scale
from lod.view import Camera


def _grid_mesh(n=40, size=4.0):
    """A wavy square sheet, n x n quads, deforming between the keyframes."""
    x = np.linspace(-size / 2, size / 2, n + 1)
    X, Z = np.meshgrid(x, x, indexing="ij")
    p0 = np.c_[X.ravel(), 0.2 * np.sin(2 * X.ravel()), Z.ravel()]
    p1 = p0 + np.c_[np.zeros(X.size), 0.3 * np.cos(3 * Z.ravel()), 0.1 * X.ravel()]
    i = np.arange(n * n)
    a = (i // n) * (n + 1) + (i % n)
    tri = np.r_[np.c_[a, a + 1, a + n + 2], np.c_[a, a + n + 2, a + n + 1]]
    return p0, p1, tri


@pytest.fixture(scope="module")
def hier():
    p0, p1, tri = _grid_mesh()
    return build_hierarchy(p0, p1, tri, leaf_triangles=20, seed=0, progress=False)


def _view(pos, target, fov=60.0, size=(640, 480)):
    cam = Camera.look_at(pos, target, fov_y=fov, near=0.05, far=500.0)
    planes = cam.frustum_planes(size[0] / size[1])
    # the hierarchy is in world space; the model matrix makes it camera-relative
    model = np.hstack([np.eye(3), -np.asarray(pos, float).reshape(3, 1)])
    return planes, model, viewport_scale(size[1], fov)


def _ancestors(h, i):
    out = []
    while h.parent[i] >= 0:
        i = h.parent[i]
        out.append(i)
    return out


def _assert_same(a, b):
    assert np.array_equal(a.point_ranges, b.point_ranges) and np.array_equal(a.point_nodes, b.point_nodes)
    assert np.array_equal(a.tri_ranges, b.tri_ranges) and np.array_equal(a.tri_nodes, b.tri_nodes)


def test_kernel_matches_reference_over_random_views(hier):
    rng = np.random.default_rng(0)
    for _ in range(25):
        pos = rng.uniform(-8, 8, 3)
        pos[1] = rng.uniform(0.5, 8)
        planes, model, vs = _view(pos, rng.uniform(-1, 1, 3))
        u = float(rng.uniform())
        for splat in (1.0, 2.0, 3.0):
            _assert_same(traverse(hier, u, planes, vs, splat, model),
                         traverse_reference(hier, u, planes, vs, splat, model))


def test_kernel_matches_reference_with_rotated_scaled_instances(hier):
    rng = np.random.default_rng(1)
    cam_pos = np.array([0.0, 3.0, 12.0])
    planes, _, vs = _view(cam_pos, (0.0, 0.0, 0.0))
    for _ in range(20):
        a = rng.uniform(0, 2 * np.pi)
        rot = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]) * rng.uniform(0.2, 3.0)
        model = np.hstack([rot, (rng.uniform(-6, 6, 3) - cam_pos).reshape(3, 1)])
        u = float(rng.uniform())
        _assert_same(traverse(hier, u, planes, vs, 2.0, model), traverse_reference(hier, u, planes, vs, 2.0, model))


def test_no_node_is_drawn_together_with_its_descendants_and_everything_is_represented(hier):
    """A point node excludes its whole subtree; without culling each triangle is drawn once, as points or itself."""
    planes, model, vs = _view((0.0, 60.0, 0.01), (0.0, 0.0, 0.0), fov=90)
    for splat in (0.2, 1.0, 3.0, 50.0):
        res = traverse(hier, 0.4, planes, vs, splat, model)
        pn = set(res.point_nodes.tolist())
        drawn = pn | set(res.tri_nodes.tolist())
        for i in pn:
            assert not (set(_ancestors(hier, i)) & pn)
        for i in drawn:
            assert not (set(_ancestors(hier, i)) & pn), "a descendant of a point node was drawn"
        # completeness: each triangle is stored at a drawn node, or below a point node
        covered = np.zeros(hier.tri_order.size, bool)
        for s, c in res.tri_ranges:
            covered[s:s + c] = True
        for i in range(hier.n_nodes):
            if set(_ancestors(hier, i)) & pn or i in pn:
                s = hier.tri_start[i]
                covered[s:s + hier.tri_count[i]] = True
        assert covered.all()


def test_far_view_draws_root_points_and_near_view_descends(hier):
    planes, model, vs = _view((0.0, 2.0, 400.0), (0.0, 0.0, 0.0))
    far = traverse(hier, 0.0, planes, vs, 2.0, model)
    assert far.point_nodes.tolist() == [0] and far.points == hier.point_count[0, 0]
    planes, model, vs = _view((0.0, 3.0, 5.0), (0.0, 0.0, 0.0))
    near = traverse(hier, 0.0, planes, vs, 2.0, model)
    assert 0 not in near.point_nodes and near.points + near.triangles > far.points


def test_culls_what_is_outside(hier):
    planes, model, vs = _view((0.0, 2.0, 10.0), (0.0, 2.0, 30.0))  # looking away
    res = traverse(hier, 0.5, planes, vs, 1.0, model)
    assert res.points == 0 and res.triangles == 0
    # looking at one corner: the opposite corner's nodes are not drawn
    planes, model, vs = _view((-3.0, 1.5, -3.0), (-1.8, 0.0, -1.8), fov=20)
    res = traverse(hier, 0.5, planes, vs, 1.0, model)
    assert res.points + res.triangles > 0
    box = hier.box_at(0.5)
    drawn = np.concatenate([res.point_nodes, res.tri_nodes])
    far_corner = (box[:, 0, 0] > 0.5) & (box[:, 0, 2] > 0.5)
    assert far_corner.any() and not far_corner[drawn].any()


def test_camera_inside_the_box_descends(hier):
    box = hier.box_at(0.3)
    inside = 0.5 * (box[0, 0] + box[0, 1])
    planes, model, vs = _view(inside, inside + [0.0, -1.0, 0.1])
    res = traverse(hier, 0.3, planes, vs, 1e9, model)  # any finite spacing would pass this splat size
    assert 0 not in res.point_nodes
    for i in res.point_nodes:  # nodes drawn as points are in front of the camera
        cs = box[i]
        assert not np.all((cs[0] <= inside) & (inside <= cs[1]))
    assert np.array_equal(res.point_ranges, traverse_reference(hier, 0.3, planes, vs, 1e9, model).point_ranges)


def test_interval_selection_follows_u(hier):
    planes, model, vs = _view((0.0, 2.0, 400.0), (0.0, 0.0, 0.0))
    m = hier.intervals
    for j in range(m):
        res = traverse(hier, (j + 0.5) / m, planes, vs, 2.0, model)
        assert res.point_ranges[0, 0] == hier.point_start[0, j]
    assert traverse(hier, 1.0, planes, vs, 2.0, model).point_ranges[0, 0] == hier.point_start[0, m - 1]


def test_bad_arguments_are_rejected(hier):
    planes, model, vs = _view((0.0, 2.0, 10.0), (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="planes"):
        traverse(hier, 0.0, planes[:5], vs, 1.0)
    with pytest.raises(ValueError, match="splat_size"):
        traverse(hier, 0.0, planes, vs, 0.0)
    with pytest.raises(ValueError, match="model"):
        traverse(hier, 0.0, planes, vs, 1.0, np.eye(2))
    res = traverse(hier, float("nan"), planes, vs, 1.0, model)  # NaN time clamps to 0
    assert res.points + res.triangles > 0
