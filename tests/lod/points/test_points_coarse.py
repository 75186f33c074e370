"""Coarser than the root (lod/points/coarse.py): farthest-point order against its
numpy reference and its covering radii; the traversal draws a prefix only when
its spacing projects within the splat (and the smallest such); the parallel
instance traversal equals the serial one."""
import numpy as np
import pytest

from lod.points import coarse
from lod.points import jobs
from lod.points.octree import build_hierarchy
from lod.points.traverse import traverse, traverse_reference, viewport_scale
from lod.view import Camera
from sim.procedural import humanoid


def test_farthest_order_matches_the_reference_and_covers_within_its_radii():
    rng = np.random.default_rng(1)
    p0 = rng.normal(size=(70, 3))
    p1 = p0 + rng.normal(scale=0.3, size=(70, 3))
    p0[5] = p0[6]
    p1[5] = p1[6]  # coincident points
    o, r = coarse.farthest_order(p0, p1)
    on, rn = coarse.farthest_order_numpy(p0, p1)
    assert np.array_equal(o, on) and np.allclose(r, rn, rtol=0, atol=1e-12)
    assert sorted(o.tolist()) == list(range(70)) and r[-1] == 0.0
    assert (np.diff(r) <= 1e-12).all()  # covering radii never grow
    d = np.maximum(np.linalg.norm(p0[:, None] - p0[None], axis=2), np.linalg.norm(p1[:, None] - p1[None], axis=2))
    for m in (1, 2, 5, 17, 69):
        assert d[:, o[:m]].min(axis=1).max() <= r[m - 1] + 1e-12
    assert coarse.farthest_order(np.zeros((0, 3)), np.zeros((0, 3)))[0].shape == (0,)


def test_prefix_table_spacings_fall_to_the_root_spacing():
    r = np.array([4.0, 3.0, 2.5, 1.0, 0.5, 0.2, 0.0])
    c, s = coarse.prefix_table(r, 0.1)
    assert c.tolist() == [1, 2, 4, 7]
    assert np.allclose(s, [8.1, 6.1, 2.1, 0.1])


@pytest.fixture(scope="module")
def walker():
    """The root of a walker's segment with coarse prefixes, and the same root without."""
    from lod.points.mode import keyframed_character, segment_arrays
    from lod.full.reps import build_keyframed_rep

    kf = build_keyframed_rep(keyframed_character(humanoid(1500, 2), 3), key="w")
    arrays = segment_arrays(kf, 0)
    h = build_hierarchy(*arrays, seed=0, progress=False)
    plain = build_hierarchy(*arrays, seed=0, progress=False)
    coarse.add_coarse(h)
    return h, plain


def _far(dist, size=(640, 480), fov=40.0):
    cam = Camera.look_at((0.0, 1.0, dist), (0.0, 1.0, 0.0), fov_y=fov, near=0.1, far=1e5)
    planes = cam.frustum_planes(size[0] / size[1])
    model = np.hstack([np.eye(3), -np.array([[0.0], [1.0], [dist]])])
    return planes, model, viewport_scale(size[1], fov)


def test_a_prefix_is_drawn_only_within_the_splat_and_is_the_smallest_that_is(walker):
    h, plain = walker
    assert h.coarse_count.shape[0] == h.intervals and h.coarse_count[:, 0].min() == 1
    seen = set()
    for dist in np.geomspace(3.0, 3000.0, 40):
        planes, model, vs = _far(dist)
        for splat in (1.0, 2.0, 3.0):
            for u in (0.1, 0.5, 0.9):
                res = traverse(h, u, planes, vs, splat, model)
                ref = traverse_reference(h, u, planes, vs, splat, model)
                assert np.array_equal(res.point_ranges, ref.point_ranges)
                full = traverse(plain, u, planes, vs, splat, model)
                if 0 not in res.point_nodes.tolist():  # the root refined: exactly the plain traversal
                    assert np.array_equal(res.point_ranges, full.point_ranges)
                    continue
                j = int(np.flatnonzero(h.points_at(0, u).start == h.point_start[0])[0])
                m = int(res.point_ranges[0, 1])
                f = 1.0 / dist * vs  # scale 1; the root's nearest depth is about dist
                cs = h.coarse_spacing[j]
                cc = h.coarse_count[j]
                q = int(np.flatnonzero(cc == m)[0])
                box = h.box_at(u)[0]
                dmin = dist - box[1, 2]  # the nearest corner's depth
                assert cs[q] * f * dist / dmin <= splat + 1e-9  # chosen only within the splat ...
                if q > 0:  # ... and the next coarser prefix is not
                    assert cs[q - 1] / dmin * vs > splat
                assert m <= int(h.point_count[0, j])
                seen.add(m == 1)
    assert seen == {True, False}  # both one splat and larger prefixes occurred


@pytest.mark.parametrize("k", [1, 37, 5000])
def test_parallel_instance_traversal_equals_the_serial_one(walker, monkeypatch, k):
    h, _ = walker
    rng = np.random.default_rng(k)
    data = np.zeros((k, 16))
    yaw = rng.uniform(-3, 3, k)
    data[:, 0], data[:, 2], data[:, 5], data[:, 8], data[:, 10] = np.cos(yaw), np.sin(yaw), 1, -np.sin(yaw), np.cos(yaw)
    data[:, 3] = rng.uniform(-40, 40, k)
    data[:, 7] = -1.0
    data[:, 11] = -rng.uniform(2.0, 400.0, k)
    data[:, 12] = rng.uniform(0, 1, k)
    cam = Camera.look_at((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), fov_y=50.0, near=0.1, far=1e4)
    planes = cam.frustum_planes(4 / 3)
    monkeypatch.setattr(jobs, "TRAVERSE_PARALLEL_MIN", 10 ** 9)
    serial = jobs.traverse_instances(h, data, planes, 500.0, 2.0, totals=True)
    assert jobs.traverse_chunks(k) == 1
    monkeypatch.setattr(jobs, "TRAVERSE_PARALLEL_MIN", 8)
    h._jobs_per_instance = 1  # force retries of the chunked kernel
    par = jobs.traverse_instances(h, data, planes, 500.0, 2.0, totals=True)
    if k >= 8:
        assert jobs.traverse_chunks(k) > 1
    for a, b in zip(serial, par):
        assert np.array_equal(a, b)
    ref_p, ref_t = jobs.traverse_instances_reference(h, data, planes, 500.0, 2.0)
    assert np.array_equal(par[0], ref_p) and np.array_equal(par[1], ref_t)
