"""The one traversal job writer (lod/points/jobs.py) that mode points, the follow path and mode auto's flat pass
share: against the per-instance reference (lod.points.traverse.traverse per instance), with the in-line root
decision on and off, serial and in chunks (with capacity retries), on one hierarchy and on a forest of
hierarchies with bins, on the characters the project generates (sim.procedural.humanoid: baked octrees per
keyframe pair and the hierarchy that follows the animation, node boxes in joint frames)."""
from types import SimpleNamespace

import numpy as np
import pytest

from lod.full.reps import build_keyframed_rep
from lod.points import jobs
from lod.points import mode as pm
from lod.points.coarse import add_coarse
from lod.points.octree import build_hierarchy
from lod.points.rep import HierarchyCache
from lod.points.traverse import NO_JOINTS, viewport_scale
from lod.view import Camera
from sim.procedural import humanoid

VIEWS = [Camera.look_at((0, 1.6, 8.0), (0, 1.0, -10.0)), Camera.look_at((0, 40.0, 60.0), (0, 0, -60.0)),
         Camera.look_at((0, 300.0, 400.0), (0, 0, -100.0))]
VS = viewport_scale(240, VIEWS[0].fov_y)


@pytest.fixture(scope="module")
def baked():
    """Three segment octrees of a generated humanoid (two with coarse prefixes, one without)."""
    kf = build_keyframed_rep(pm.keyframed_character(humanoid(900, 4), 3), key="jobs")
    hs = []
    for s in range(3):
        h = build_hierarchy(*pm.segment_arrays(kf, s), seed=s, progress=False)
        if s != 1:
            add_coarse(h)
        hs.append(h)
    return hs


@pytest.fixture(scope="module")
def follow(tmp_path_factory):
    reps, _ = pm.build([humanoid(600, 3)], ["h"], [30], {"animation": "follow", "keyframes": 2},
                       cache=HierarchyCache(tmp_path_factory.mktemp("jobs")), progress=False)
    assert getattr(reps[0], "follow", False)
    return reps[0]


def _crowd(rng, k, cam, col12):
    pos = np.column_stack([rng.uniform(-60, 60, k), np.zeros(k), rng.uniform(-400, 10, k)])
    th, s = rng.uniform(0, 6.3, k), rng.uniform(0.8, 1.3, k)
    d = np.zeros((k, 16), np.float32)
    d[:, 0], d[:, 2], d[:, 5] = s * np.cos(th), s * np.sin(th), s
    d[:, 8], d[:, 10] = -s * np.sin(th), s * np.cos(th)
    d[:, [3, 7, 11]] = pos - np.asarray(cam.position)
    d[:, 12] = col12(k)
    return d


def _u(rng):
    def col(k):
        u = rng.uniform(-0.1, 1.1, k)
        u[:4] = [np.nan, np.inf, -1.0, 2.0]
        return u
    return col


def _same(a, b):
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert x.dtype == y.dtype and x.shape == y.shape
        np.testing.assert_array_equal(x, y)


def _all_ways(h, d, planes, p, monkeypatch):
    """traverse_instances with totals and deepest, root off (serial), root on (serial) and root on and off in
    chunks with capacity retries: all equal; returns the first."""
    monkeypatch.setattr(jobs, "TRAVERSE_PARALLEL_MIN", 10 ** 9)
    want = jobs.traverse_instances(h, d, planes, VS, p, totals=True, deepest=True)
    assert jobs.traverse_chunks(d.shape[0]) == 1
    _same(jobs.traverse_instances(h, d, planes, VS, p, totals=True, deepest=True, root=True), want)
    monkeypatch.setattr(jobs, "TRAVERSE_PARALLEL_MIN", 64)
    for root in (False, True):
        h._jobs_per_instance = 1  # force retries of the chunked writer
        _same(jobs.traverse_instances(h, d, planes, VS, p, totals=True, deepest=True, root=root), want)
    if d.shape[0] >= 64 and jobs.numba.get_num_threads() > 1:
        assert jobs.traverse_chunks(d.shape[0]) > 1
    return want


def test_baked_octrees_equal_the_reference_root_on_and_off(baked, monkeypatch):
    rng = np.random.default_rng(1)
    for h in baked:
        for cam in VIEWS:
            planes = cam.frustum_planes(4 / 3)
            d = _crowd(rng, 300, cam, _u(rng))
            for p in (1, 2, 3):
                pj, tj, ps, ts, deep = _all_ways(h, d, planes, p, monkeypatch)
                rp, rt = jobs.traverse_instances_reference(h, d, planes, VS, p)
                np.testing.assert_array_equal(pj, rp)
                np.testing.assert_array_equal(tj, rt)
                np.testing.assert_array_equal(ps, np.bincount(pj[:, 0], pj[:, 2], d.shape[0]).astype(np.int64))
                np.testing.assert_array_equal(ts, np.bincount(tj[:, 0], tj[:, 2], d.shape[0]).astype(np.int64))
                assert ((deep >= 0) == ((ps > 0) | (ts > 0))).all()


def test_follow_hierarchy_equals_the_reference_root_on_and_off(follow, monkeypatch):
    """Node boxes in joint frames, whole and fractional baked rows, non-finite and out-of-range frame
    coordinates; follow_traverse is the writer with the root on, totals and deepest."""
    rng = np.random.default_rng(2)
    n_root = n_deep = 0
    for part in range(follow.n_parts):
        h = follow.view(part)
        F = h.joint_table.shape[0]

        def rows(k):
            f = rng.uniform(0, F - 1, k)
            f[::2] = np.round(f[::2])
            f[:6] = [np.nan, -3.0, 1e6, np.inf, 0.0, F - 1]
            return f

        for cam in VIEWS:
            planes = cam.frustum_planes(4 / 3)
            for k in (200, 3000):
                d = _crowd(rng, k, cam, rows)
                for p in (1, 2, 3):
                    want = _all_ways(h, d, planes, p, monkeypatch)
                    _same(jobs.follow_traverse(h, d, planes, VS, p), want)
                    if k <= 200:
                        rp, rt = jobs.traverse_instances_reference(h, d, planes, VS, p)
                        np.testing.assert_array_equal(want[0], rp)
                        np.testing.assert_array_equal(want[1], rt)
                    n_root += int((want[4] <= 0).sum())
                    n_deep += int((want[4] > 0).sum())
    assert n_root > 1000 and n_deep > 100, (n_root, n_deep)


def _forest_arrays(hs):
    """The forest arrays of jobs.write_jobs for hierarchies ``hs`` (lod.auto.flat_points.build_forest)."""
    from lod.auto.flat_points import build_forest

    f = build_forest({0: SimpleNamespace(hierarchies=hs[:2]), 1: SimpleNamespace(hierarchies=hs[2:])})
    arr = f.arrays()
    assert arr[-2:] == NO_JOINTS
    return f, arr


def test_forest_with_bins_equals_one_hierarchy_per_bin(baked, monkeypatch):
    """Mode auto's flat pass: instances sorted by bin, each bin traversed in its own hierarchy (mapped out of
    order, a spare bin at the end), job rows numbered within the bin: the tables are the per-hierarchy
    tables one after another, the per-bin counts their lengths, root on and off, serial and chunked."""
    f, arr = _forest_arrays(baked)
    rng = np.random.default_rng(3)
    bin_h = np.array([2, 0, 1, 0], np.int64)
    for cam in VIEWS:
        planes = cam.frustum_planes(4 / 3)
        for counts in ([300, 200, 100], [0, 50, 0], [2000, 1500, 1800]):
            K = sum(counts)
            d = _crowd(rng, K, cam, _u(rng))
            row0 = np.concatenate([[0], np.cumsum(counts), [K]]).astype(np.int64)
            kbin = np.repeat(np.arange(3), counts).astype(np.int64)
            for p in (1, 2, 3):
                monkeypatch.setattr(jobs, "TRAVERSE_PARALLEL_MIN", 10 ** 9)
                per = [jobs.traverse_instances(baked[bin_h[b]], d[row0[b]:row0[b + 1]], planes, VS, p, totals=True)
                       for b in range(3)]
                for lim, root in ((10 ** 9, False), (10 ** 9, True), (64, False), (64, True)):
                    monkeypatch.setattr(jobs, "TRAVERSE_PARALLEL_MIN", lim)
                    f._jobs_per_instance = 1
                    pj, tj, ps, ts, deep, pbin, tbin = jobs.write_jobs(arr, d, planes, VS, p, f, root=root,
                                                                       bins=(kbin, bin_h, row0))
                    assert deep is None and pbin.shape == tbin.shape == (4,) and pbin[3] == tbin[3] == 0
                    np.testing.assert_array_equal(pbin[:3], [x[0].shape[0] for x in per])
                    np.testing.assert_array_equal(tbin[:3], [x[1].shape[0] for x in per])
                    _same((pj, tj, ps, ts), tuple(np.concatenate([x[i] for x in per]) for i in range(4)))
                    # lod.auto.flat_points.traverse: the same writer, the bins' first jobs
                    if root:
                        from lod.auto import flat_points as fp

                        got = fp.traverse(f, d, kbin, bin_h, row0[:4], planes, VS, p)
                        _same(got[:4], (pj, tj, ps, ts))
                        np.testing.assert_array_equal(got[4], np.r_[0, np.cumsum(pbin[:3])])
                        np.testing.assert_array_equal(got[5], np.r_[0, np.cumsum(tbin[:3])])


def test_root_decision_at_the_kernels_thresholds(baked):
    """Instances placed at the depths where the traversal's decision changes (found by bisection on the
    kernel's own outcome) and within 1e-12 of them: the root decided in line gives the kernel's jobs
    exactly (count of the coarse prefix included)."""
    h = baked[0]
    assert h.coarse_count is not None and h.coarse_count.shape[-1] > 1
    cam = Camera.look_at((0, 0.0, 0.0), (0, 0.0, -1.0))
    planes = cam.frustum_planes(1.0)

    def data(zs, u=0.3, yaw=0.4):
        zs = np.asarray(zs, np.float64)
        d = np.zeros((zs.shape[0], 16), np.float32)
        d[:, :12] = [np.cos(yaw), 0, np.sin(yaw), 0.1, 0, 1, 0, -0.9, -np.sin(yaw), 0, np.cos(yaw), 0]
        d[:, 11] = zs
        d[:, 12] = u
        return d

    def outcome(z):
        pj, tj = jobs.traverse_instances(h, data([z]), planes, 240.0, 2.0)
        return pj[:, 1:].tobytes(), tj.shape[0]

    zs = -np.geomspace(0.5, 400.0, 300)
    cuts = []
    for a, b in zip(zs[:-1], zs[1:]):
        if outcome(a) != outcome(b):
            for _ in range(200):
                mid = 0.5 * (a + b)
                if mid in (a, b):
                    break
                a, b = (mid, b) if outcome(mid) == outcome(a) else (a, mid)
            cuts.append(a)
    assert len(cuts) >= 3
    z = np.concatenate([zs, [c + dz for c in cuts for dz in (-1e-12, -1e-14, 0.0, 1e-14, 1e-12)]])
    d = data(z)
    off = jobs.traverse_instances(h, d, planes, 240.0, 2.0, totals=True, deepest=True)
    on = jobs.traverse_instances(h, d, planes, 240.0, 2.0, totals=True, deepest=True, root=True)
    _same(on, off)
    assert (off[4] == 0).sum() > 100 and (off[4] > 0).sum() > 10
