"""Occlusion culling of point-hierarchy nodes (render/points/occlusion.py, render/points/draw.py): the numba
kernels against their numpy references, and on a scene with known occluders the culled image equals
the unculled one while the hidden instances' nodes are culled."""
import sys
from pathlib import Path

import numpy as np
import pytest

from lod.points import mode as pm
from lod.points import rep as pm_rep
from lod.view import Camera
from render.points import occlusion as occ
from render.renderer import Renderer
from sim.state import CrowdState

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_points_render import sphere_character  # noqa: E402

SIZE = (256, 192)


def _random_boxes(rng, n):
    c = rng.uniform(-30, 30, (n, 3))
    e = rng.uniform(0.01, 4.0, (n, 3))
    model = np.zeros((n, 12))
    for i in range(n):
        a = rng.uniform(0, 2 * np.pi)
        s = rng.uniform(0.5, 2.0)
        R = s * np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
        model[i] = np.hstack([R, rng.uniform(-20, 20, (3, 1))]).reshape(-1)
    return c - e, c + e, model


def _view_proj(cam, size=SIZE):
    return cam.projection(size[0] / size[1]) @ cam.view_matrix()


def test_bounds_kernel_matches_reference_and_holds_every_corner():
    rng = np.random.default_rng(3)
    lo, hi, model = _random_boxes(rng, 400)  # some boxes reach behind the eye plane
    cam = Camera.look_at((0.0, 2.0, 0.0), (0.0, 1.0, -10.0), fov_y=50.0, near=0.5, far=200.0)
    vp = _view_proj(cam)
    r1, z1 = occ.job_bounds(lo, hi, model, vp, SIZE, 3.0)
    r2, z2 = occ.job_bounds_reference(lo, hi, model, vp, SIZE, 3.0)
    np.testing.assert_array_equal(r1, r2)
    np.testing.assert_allclose(z1, z2, rtol=0, atol=1e-12)
    assert (z1 < 0).sum() > 10 and (z1 > 0).sum() > 10 and (r1[:, 0] > r1[:, 2]).sum() > 10
    # every point of an on-screen testable box projects inside its rectangle, no nearer than zmin
    for j in np.flatnonzero((z1 > 0) & (r1[:, 0] <= r1[:, 2]))[:50]:
        p = rng.uniform(lo[j], hi[j], (64, 3))
        q = p @ model[j].reshape(3, 4)[:, :3].T + model[j].reshape(3, 4)[:, 3]
        clip = np.c_[q, np.ones(64)] @ vp.T
        ndc = clip[:, :3] / clip[:, 3:]
        x = (ndc[:, 0] * 0.5 + 0.5) * SIZE[0]
        y = (ndc[:, 1] * 0.5 + 0.5) * SIZE[1]
        on = (x >= 0) & (x < SIZE[0]) & (y >= 0) & (y < SIZE[1])
        assert np.all(np.floor(x[on]) >= r1[j, 0]) and np.all(np.floor(x[on]) <= r1[j, 2])
        assert np.all(np.floor(y[on]) >= r1[j, 1]) and np.all(np.floor(y[on]) <= r1[j, 3])
        assert np.all(ndc[:, 2] * 0.5 + 0.5 >= z1[j] - 1e-9)


def test_pyramid_and_test_kernels_match_references():
    rng = np.random.default_rng(5)
    depth = rng.uniform(0.2, 1.0, (37, 53)).astype(np.float32)
    depth[10:20, 5:30] = 0.1
    a, b = occ.depth_pyramid(depth), occ.depth_pyramid_reference(depth)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    assert a[2][-1] == 1 and a[3][-1] == 1 and a[0][-1] == depth.max()
    n = 500
    x0 = rng.integers(-2, 55, n)
    y0 = rng.integers(-2, 39, n)
    rect = np.stack([x0, y0, x0 + rng.integers(-1, 30, n), y0 + rng.integers(-1, 20, n)], 1)
    rect = np.clip(rect, 0, [52, 36, 52, 36])
    z = rng.uniform(-0.1, 1.0, n)
    for span in (2, 8):
        h1 = occ.occluded(rect, z, a, span=span)
        np.testing.assert_array_equal(h1, occ.occluded_reference(rect, z, a, span=span))
        # conservative: hidden by the pyramid => hidden by the exact per-pixel maximum
        exact = np.array([z[j] > depth[r[1]:r[3] + 1, r[0]:r[2] + 1].max() + occ.DEPTH_EPSILON
                          if r[0] <= r[2] and r[1] <= r[3] else True for j, r in enumerate(rect)])
        assert not np.any(h1 & ~exact)
        assert h1.sum() > 20
    on = (rect[:, 0] <= rect[:, 2]) & (rect[:, 1] <= rect[:, 3])
    assert not occ.occluded(rect, np.full(n, -1.0), a)[on].any()


def test_occluder_depth_takes_the_nearer_of_triangles_and_splat_footprints():
    w, h, m = 6, 5, 2
    gl = np.ones((h, w), np.float32)
    gl[0, 0] = 0.3
    keys = np.full((h + m, w + m), 0xFFFFFFFF, np.uint32)
    keys[m + 2, m + 3] = np.float32(0.5).view(np.uint32)  # anchor of pixel (3, 2)
    d1 = occ.occluder_depth(gl.reshape(-1), keys.reshape(-1), (w, h), m, splat=1)
    assert d1[0, 0] == np.float32(0.3) and d1[2, 3] == np.float32(0.5) and (d1 < 1).sum() == 2
    d2 = occ.occluder_depth(gl.reshape(-1), keys.reshape(-1), (w, h), m, splat=2)  # covers (3..4, 2..3)
    assert (d2 == np.float32(0.5)).sum() == 4 and d2[3, 4] == np.float32(0.5)
    assert np.isfinite(d2).all()


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    cache = pm_rep.HierarchyCache(tmp_path_factory.mktemp("cache"))
    reps, sel = pm.build([sphere_character()], ["ball"], [30], {"splat_size": 2}, cache=cache,
                         progress=lambda it, d: it)
    return reps[0], sel


#: a wall of 7 balls (radius ~1.1, centres 1 m up) 12 m in front of the camera (x = -6 .. 6); 3 balls on
#: the lines of sight through wall balls' centres, 18-20 m behind them (hidden, boxes of every node
#: included), and 2 balls behind the wall raised so that their tops show over it (partly visible)
WALL = [(x, 0.0, 0.0) for x in np.linspace(-6.0, 6.0, 7)]
HIDDEN = [(-4.0 * 32.0 / 12.0, 0.0, -20.0), (0.0, 0.0, -20.0), (2.0 * 30.0 / 12.0, 0.0, -18.0)]
PARTLY = [(-3.0, 1.5, -8.0), (3.0, 1.5, -8.0)]
CAM = Camera.look_at((0.0, 1.0, 12.0), (0.0, 1.0, 0.0), fov_y=50.0, near=0.5, far=200.0)


def _state(positions):
    st = CrowdState.empty(len(positions))
    st.position[:] = np.asarray(positions, np.float64)
    st.anim_time[:] = 0.4
    return st


def test_occlusion_keeps_the_image_and_culls_the_hidden_balls(gl_ctx, ball, monkeypatch):
    monkeypatch.setattr(occ, "OCCLUSION_MIN_SHARE", 0.0)  # never paused here (the hidden balls are far: little work)
    rep, sel = ball
    r = Renderer(SIZE, ctx=gl_ctx)
    try:
        r.upload(rep)
        d = r.drawer("points")
        dl = sel.select(_state(WALL + HIDDEN + PARTLY), CAM, SIZE)
        hidden_only = sel.select(_state(HIDDEN), CAM, SIZE)
        hidden_jobs = sum(b.point_jobs.shape[0] for b in hidden_only.batches)
        hidden_pts = hidden_only.stats["points"]
        assert hidden_jobs > 0 and dl.stats["points"] > 5000
        d.occlusion = False
        r.draw(dl)
        ref = r.read_pixels()
        assert d.last_counts["occluded_point_jobs"] == 0
        counts = []
        for _ in range(3):  # the first frame has no visible set yet; the next ones use the last one's
            d.occlusion = True
            r.draw(dl)
            img = r.read_pixels()
            np.testing.assert_array_equal(img, ref)  # nothing visible dropped
            counts.append(dict(d.last_counts))
        c = counts[-1]
        # every node of the hidden balls is culled (and nodes of the partly visible ones may be)
        assert c["occluded_point_jobs"] >= hidden_jobs and c["occluded_points"] >= hidden_pts
        assert c["points"] + c["occluded_points"] == dl.stats["points"]
        # the partly visible balls show: without them the image differs
        d.occlusion = False
        r.draw(sel.select(_state(WALL + HIDDEN), CAM, SIZE))
        assert (np.abs(r.read_pixels().astype(int) - ref.astype(int)).sum(2) > 0).sum() > 50
        # and without the hidden ones it does not
        r.draw(sel.select(_state(WALL + PARTLY), CAM, SIZE))
        np.testing.assert_array_equal(r.read_pixels(), ref)
    finally:
        r.release()


def test_occlusion_with_nothing_hidden_and_gl_points_draws_everything(gl_ctx, ball, monkeypatch):
    monkeypatch.setattr(occ, "OCCLUSION_MIN_SHARE", 0.0)
    rep, sel = ball
    r = Renderer(SIZE, ctx=gl_ctx)
    try:
        r.upload(rep)
        d = r.drawer("points")
        dl = sel.select(_state(WALL), CAM, SIZE)
        d.occlusion = False
        r.draw(dl)
        ref = r.read_pixels()
        d.occlusion = True
        for _ in range(2):
            r.draw(dl)
            np.testing.assert_array_equal(r.read_pixels(), ref)
        assert d.last_counts["points"] == dl.stats["points"]
        d.path = "gl_points"  # the reference path draws without culling
        r.draw(sel.select(_state(WALL + HIDDEN), CAM, SIZE))
        assert d.last_counts["occluded_point_jobs"] == 0
    finally:
        r.release()


def test_occlusion_key_of_mode_points_reaches_the_drawer():
    """`[lod] occlusion` is a key of mode points, and the engine's toggle (`O` in crowd fly) sets it on the
    open renderer's points drawer."""
    from types import SimpleNamespace

    from crowd.engine import Engine
    from lod import modes

    p = modes.mode_params("points")["occlusion"]
    assert p.default is False
    pts, clu = SimpleNamespace(occlusion=False), SimpleNamespace(on=None)
    clu.set_occlusion = lambda on: setattr(clu, "on", on)
    fake = SimpleNamespace(_modes={}, renderer=SimpleNamespace(uploaded_drawer={"points": pts, "clusters": clu}.get))
    Engine.apply_occlusion(fake, True)
    assert pts.occlusion is True and clu.on is True
    Engine.apply_occlusion(fake, False)
    assert pts.occlusion is False and clu.on is False


def test_occlusion_pauses_where_little_is_hidden(gl_ctx, ball, monkeypatch):
    """A frame whose test finds less than OCCLUSION_MIN_SHARE of the work hidden draws the next
    OCCLUSION_RETRY_FRAMES frames without the test (same image), then tests again."""
    monkeypatch.setattr(occ, "OCCLUSION_RETRY_FRAMES", 2)
    rep, sel = ball
    r = Renderer(SIZE, ctx=gl_ctx)
    try:
        r.upload(rep)
        d = r.drawer("points")
        dl = sel.select(_state(WALL), CAM, SIZE)  # nothing hidden
        r.draw(dl)
        ref = r.read_pixels()
        d.occlusion = True
        paused = []
        for _ in range(4):
            r.draw(dl)
            np.testing.assert_array_equal(r.read_pixels(), ref)
            paused.append(d.last_counts["occlusion_paused"])
        assert paused == [0, 1, 1, 0]
    finally:
        r.release()


def test_batch_bounds_equal_job_boxes_then_job_bounds(ball):
    """The drawer's fused per-batch kernel gives the bounds of job_boxes + job_bounds, job for job."""
    rep, sel = ball
    st = _state(WALL + HIDDEN + PARTLY)
    st.anim_time[:] = np.linspace(0.0, 0.95, st.n)
    dl = sel.select(st, CAM, SIZE)
    vp = CAM.projection(SIZE[0] / SIZE[1]) @ CAM.view_matrix()
    n = 0
    for b in dl.batches:
        for which in ("point_jobs", "tri_jobs"):
            j = getattr(b, which)
            j = j[j[:, 2] > 0]
            if not j.shape[0]:
                continue
            lo, hi, model, _ = occ.job_boxes([b], b.rep, rep.hierarchies, which)
            r1, z1 = occ.job_bounds(lo, hi, model, vp, SIZE, 3.0)
            r2, z2, nodes = occ.batch_bounds(rep.hierarchies[b.part], j, b.instance_data, which, vp, SIZE, 3.0)
            np.testing.assert_array_equal(r1, r2)
            np.testing.assert_allclose(z1, z2, rtol=0, atol=1e-12)
            np.testing.assert_array_equal(nodes, occ.job_nodes(rep.hierarchies[b.part], j[:, 1], which))
            n += j.shape[0]
    assert n > 20
