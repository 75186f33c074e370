"""Far crowds drawn coarser than their hierarchies' roots (lod/points/coarse.py):
the image stays within the points rule (silhouette within the splat size of the
root's image) with several times fewer points; short jobs splatted one per
thread give the same pixels as one per work group (render/points/draw.py)."""
from types import SimpleNamespace

import numpy as np
import pytest

from lod.points import mode as pm
from lod.points import rep as pm_rep
from lod.view import Camera
from sim.procedural import humanoid
from sim.state import CrowdState
from render.renderer import Renderer

from image_checks import silhouette_error  # tests/fixtures (on sys.path via tests/render/conftest.py)

SIZE = (320, 240)
BG = (0.1, 0.1, 0.12)
SPLAT = 2


@pytest.fixture(scope="module")
def far(gl_ctx, tmp_path_factory):
    c = humanoid(1500, 5)
    cache = pm_rep.HierarchyCache(tmp_path_factory.mktemp("cache"))
    params = {"splat_size": SPLAT, "keyframes": 4}
    out = {}
    for coarse in (True, False):
        reps, sel = pm.build([c], ["w"], [30], params | {"coarse": coarse}, cache=cache, progress=False)
        out[coarse] = (reps, sel)
    n = 120
    rng = np.random.default_rng(4)
    st = CrowdState.empty(n)
    st.position[:, 0] = rng.uniform(-60.0, 60.0, n)
    st.position[:, 2] = rng.uniform(-260.0, -120.0, n)  # 2-5 pixels tall
    st.heading[:] = rng.uniform(-3.0, 3.0, n)
    st.anim_time[:] = rng.uniform(0.0, 1.0, n)
    st.scale[:] = 1.0
    cam = Camera.look_at((0.0, 6.0, 0.0), (0.0, 0.0, -190.0), fov_y=40.0, near=0.5, far=1000.0)
    return SimpleNamespace(c=c, reps=out, st=st, cam=cam, gl=gl_ctx)


def _draw(gl_ctx, reps, dl):
    r = Renderer(SIZE, ctx=gl_ctx)
    try:
        for rep in reps:
            r.upload(rep)
        r.draw(dl, background=BG)
        return r.read_pixels()
    finally:
        r.release()


def _mask(img):
    bg = np.round(np.asarray(BG) * 255).astype(int)
    return np.abs(img.astype(int) - bg).max(axis=2) > 2


def test_far_crowd_coarser_than_the_root_stays_within_the_splat_of_the_root_image(far):
    reps_c, sel_c = far.reps[True]
    reps_r, sel_r = far.reps[False]
    dl_c = sel_c.select(far.st, far.cam, SIZE)
    dl_r = sel_r.select(far.st, far.cam, SIZE)
    assert dl_c.stats["instances"] == dl_r.stats["instances"] == far.st.n
    # every instance is drawn from its root alone in the reference ...
    for b in dl_r.batches:
        assert (b.point_jobs[:, 0] == np.arange(b.n_instances)).all()
    # ... and from a prefix of it here, several times fewer points
    assert dl_c.stats["points"] * 4 <= dl_r.stats["points"]
    img_c, img_r = _draw(far.gl, reps_c, dl_c), _draw(far.gl, reps_r, dl_r)
    mc, mr = _mask(img_c), _mask(img_r)
    assert mr.sum() > 300
    # the points rule: a coarser representation moves the silhouette by at most the splat size
    assert silhouette_error(mc, mr) <= SPLAT
    assert abs(int(mc.sum()) - int(mr.sum())) <= 0.35 * mr.sum()


@pytest.mark.parametrize("short", [0, 1 << 30])
def test_short_jobs_one_per_thread_splat_the_same_image(far, monkeypatch, short):
    import render.points.draw as rp

    reps, sel = far.reps[True]
    st = far.st
    near = CrowdState.empty(st.n + 3)  # a few near agents too: long jobs beside the short ones
    for name in ("position", "heading", "anim_time", "scale"):
        getattr(near, name)[:st.n] = getattr(st, name)
    near.position[st.n:] = [[-3.0, 0.0, -20.0], [2.0, 0.0, -30.0], [6.0, 0.0, -45.0]]
    near.scale[st.n:] = 1.0
    dl = sel.select(near, far.cam, SIZE)
    lens = np.concatenate([b.point_jobs[:, 2] for b in dl.batches if hasattr(b, "point_jobs")])
    assert (lens <= rp.SHORT_JOB_POINTS).any() and (lens > rp.SHORT_JOB_POINTS).any()
    ref = _draw(far.gl, reps, dl)
    monkeypatch.setattr(rp, "SHORT_JOB_POINTS", short)  # none short, then all short
    np.testing.assert_array_equal(_draw(far.gl, reps, dl), ref)


def test_a_frame_in_storage_buffer_windows_draws_the_same_pixels(far):
    """A tiny injected storage-buffer limit (16 instances, 64 jobs a binding) cuts the instances,
    point jobs and triangle items into windows (render/points/frame.py): the same image."""
    reps, sel = far.reps[True]
    st = far.st
    near = CrowdState.empty(st.n + 3)
    for name in ("position", "heading", "anim_time", "scale"):
        getattr(near, name)[:st.n] = getattr(st, name)
    near.position[st.n:] = [[0.3, 0.0, -3.0], [2.0, 0.0, -12.0], [-4.0, 0.0, -30.0]]  # triangles up close
    near.scale[st.n:] = 1.0
    dl = sel.select(near, far.cam, SIZE)
    assert sum(b.tri_jobs.shape[0] for b in dl.batches if hasattr(b, "tri_jobs")) > 0
    r = Renderer(SIZE, ctx=far.gl)
    try:
        for rep in reps:
            r.upload(rep)
        r.draw(dl, background=BG)
        ref = r.read_pixels()
        r.drawer("points").ssbo_limit = 16 * 64
        r.draw(dl, background=BG)
        img = r.read_pixels()
    finally:
        r.release()
    assert _mask(ref).sum() > 1000
    np.testing.assert_array_equal(img, ref)


def test_instance_windows_rebase_and_bound_every_piece():
    from render.points.frame import instance_windows

    rng = np.random.default_rng(0)
    jobs = np.c_[rng.integers(0, 100, 50), rng.integers(1, 5, 50), np.sort(rng.integers(0, 40, 50)),
                 np.zeros(50, np.int64)]
    assert instance_windows(jobs, 40, 40, 50)[0][1] is jobs  # fits: the table itself
    pieces = instance_windows(jobs, 40, 8, 3)
    back = []
    for first, p in pieces:
        assert first % 8 == 0 and p.shape[0] <= 3 and (0 <= p[:, 2]).all() and (p[:, 2] < 8).all()
        q = p.copy()
        q[:, 2] += first
        back.append(q)
    assert np.array_equal(np.concatenate(back), jobs)  # every job once, in order (rows sorted here)
