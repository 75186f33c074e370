"""The far tier's per-frame split (lod/far/select.py): the kernel against its numpy reference, the rows, the
threshold, and bad input."""
from types import SimpleNamespace

import numpy as np
import pytest

from lod.far import select as fs
from lod.far.footprint import measure
from lod.far.rep import FarRep
from lod.points.traverse import viewport_scale
from lod.view import Camera
from sim.state import CrowdState


def _rep(radius=1.0, centre=(0.0, 0.9, 0.1), clips=2):
    t = measure([])
    t.radius, t.centre = radius, np.asarray(centre, float)
    return FarRep("far:x", [t] * clips)


def _crowd(n=5000, seed=1):
    rng = np.random.default_rng(seed)
    st = CrowdState.empty(n)
    st.position[:, 0] = rng.uniform(-400, 400, n)
    st.position[:, 2] = rng.uniform(-2000, 50, n)
    st.position[:, 1] = rng.uniform(-1, 1, n)
    st.heading[:] = rng.uniform(-7, 7, n)
    st.scale[:] = rng.uniform(0.5, 2.0, n)
    st.clip[:] = rng.integers(0, 2, n)
    st.character[:] = rng.integers(0, 2, n)
    return st


def test_kernel_matches_reference():
    st = _crowd()
    split = fs.FarSplit([_rep(1.1), _rep(0.4, (0.2, 0.5, -0.3))], far_pixels=2.0)
    cam = Camera.look_at((10.0, 30.0, 40.0), (0.0, 0.0, -500.0), fov_y=45.0, near=0.5, far=1500.0)
    planes = cam.frustum_planes(16 / 9)
    args = (st.position, cam.position, st.heading, st.scale, st.character, st.clip, split.radius, split.centre,
            planes, cam.forward, 2.0 / viewport_scale(720, 45.0))
    got, want = fs.classify(*args), fs.classify_numpy(*args)
    assert np.array_equal(got, want)
    assert set(np.unique(got).tolist()) == {fs.CULLED, fs.NEAR, fs.FAR}  # the crowd spans all three


def test_split_threshold_rows_and_words():
    st = _crowd(2000, 2)
    st.heading[0], st.clip[0] = -0.25 * np.pi, 1
    st.position[0] = (0.0, 0.0, -1500.0)
    reps = [_rep(1.0), _rep(1.0)]
    split = fs.FarSplit(reps, far_pixels=2.0)
    cam = Camera.look_at((0.0, 5.0, 0.0), (0.0, 5.0, -10.0), fov_y=40.0, near=0.5, far=2500.0)
    size = (640, 360)
    vs = viewport_scale(size[1], cam.fov_y)
    near, batches, culled = split.split(st, cam, size, vs, cam.frustum_planes(size[0] / size[1]))
    far = np.concatenate([b.instance_ids for b in batches])
    assert np.intersect1d(near, far).size == 0 and near.size + far.size + culled == st.n
    for b in batches:
        rows = b.instance_data
        ids = b.instance_ids
        assert rows.dtype == np.float32 and rows.shape == (ids.shape[0], 4)
        assert np.allclose(rows[:, :3], st.position[ids] - cam.position, atol=1e-3)
        assert np.array_equal(rows[:, 3], st.scale[ids].astype(np.float32))
        assert np.array_equal(b.words >> 16, st.clip[ids])
        turns = (b.words & 0xFFFF) / 65536.0
        d = (turns - st.heading[ids] / (2 * np.pi)) % 1.0
        assert np.all(np.minimum(d, 1 - d) <= 1.0 / 65536)
        assert b.rep == "far:x" and b.points == ids.shape[0]
        # every far agent's sphere projects within the threshold, every near one beyond it or too close
        depth = (st.position[ids] - cam.position) @ cam.forward
        assert np.all(2.0 * st.scale[ids] * vs / (depth - 1.5 * st.scale[ids]) <= 2.0 * 1.01)
    assert 0 in far.tolist()


def test_off_and_bad_values():
    st = _crowd(100)
    cam = Camera.look_at((0.0, 5.0, 0.0), (0.0, 0.0, -10.0))
    off = fs.FarSplit([_rep()], far_pixels=0.0)
    assert not off.active
    assert off.split(st, cam, (64, 64), 50.0, cam.frustum_planes(1.0)) == (None, [], 0)
    none = fs.FarSplit([None], far_pixels=2.0)  # no table: every agent goes on
    assert not none.active
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="far_pixels"):
            fs.FarSplit([_rep()], far_pixels=bad)


def test_non_finite_agents_go_on_to_the_mode():
    """A NaN position is never drawn far: it goes on to the mode's selection, which refuses it by name."""
    st = _crowd(50)
    st.position[3] = np.nan
    st.heading[4] = np.inf
    cam = Camera.look_at((0.0, 5.0, 0.0), (0.0, 0.0, -10.0), fov_y=40.0, far=3000.0)
    split = fs.FarSplit([_rep(), _rep()], far_pixels=8.0)
    near, batches, _ = split.split(st, cam, (640, 360), viewport_scale(360, 40.0), cam.frustum_planes(16 / 9))
    far = np.concatenate([b.instance_ids for b in batches]) if batches else np.zeros(0)
    assert 3 not in far.tolist()
    for b in batches:
        assert np.isfinite(b.instance_data).all()
