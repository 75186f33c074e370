"""Drawing samples that follow the animation (render/points/follow.py, shaders points_pose/points_place and the
PLACED splat, triangle and GL_POINTS variants): the GPU's posed vertices and placed samples against the CPU, pose
sharing, placement rounds under a small storage limit, morph targets and keyframes, the image against full
detail and against the per-keyframe-pair octrees."""
import dataclasses

import numpy as np
import pytest

from crowd.image_metrics import psnr
from lod.full.mode import NoLodSelector
from lod.full.reps import build_rep
from lod.full import frames as full_frames
from lod.points import mode as pm
from lod.points.rep import HierarchyCache
from lod.view import Camera
from render.renderer import Renderer
from sim.procedural import humanoid
from sim.state import CrowdState

SIZE = (160, 160)
BG = (0.1, 0.1, 0.12)
CAM = Camera.look_at((0.0, 1.1, 3.2), (0.0, 0.95, 0.0), fov_y=45.0, near=0.05, far=200.0)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return HierarchyCache(tmp_path_factory.mktemp("follow"))


@pytest.fixture(scope="module")
def walker():
    return humanoid(1200, 3)


def _build(ch, cache, **params):
    reps, sel = pm.build([ch], ["w"], [30], {"animation": "follow", **params}, cache=cache, progress=False)
    return reps, sel


def _state(times, clip=0, xs=None):
    st = CrowdState.empty(len(times))
    st.anim_time[:] = times
    st.clip[:] = clip
    if xs is not None:
        st.position[:, 0] = xs
    return st


def _draw(gl_ctx, reps, dl, size=SIZE, limit=None):
    r = Renderer(size, ctx=gl_ctx)
    try:
        for rep in reps:
            r.upload(rep)
        if limit is not None:
            r.drawer("points").ssbo_limit = limit
        r.draw(dl, background=BG)
        img = r.read_pixels()
        d = r.uploaded_drawer("points")
        placed = None if d is None or "follow_placed" not in d._bufs else \
            np.frombuffer(d._bufs["follow_placed"].read(), np.uint32).reshape(-1, 4).copy()
        return img, (dict(d.last_counts) if d is not None else {}), placed
    finally:
        r.release()


def _decode(words, lo, scale):
    from render.points.samples import unpack_samples

    w = np.zeros((words.shape[0], 8), np.uint32)
    w[:, 0], w[:, 1] = words[:, 0], words[:, 1]
    w[:, 6] = words[:, 2]
    return unpack_samples(w, lo, scale)


def test_gpu_poses_and_places_what_the_cpu_does(gl_ctx, walker, cache):
    """One copy at one pose: the pose pass's vertices (follow numbering) and the placement pass's samples, read
    back from the placed buffer, are the CPU's skinning of the same baked row and the barycentric blend of its
    posed corners, within the unorm16 quantisation of the pose box; normals within a few degrees."""
    from render.points.follow import pose_box

    reps, sel = _build(walker, cache)
    rep = reps[0]
    cam = Camera.look_at((0.0, 1.1, 9.0), (0.0, 0.95, 0.0), fov_y=45.0, near=0.05, far=200.0)
    dl = sel.select(_state([0.4]), cam, SIZE)
    (b,) = [b for b in dl.batches if getattr(b, "pose", None) is not None]
    assert b.pose.shape == (1,) and b.pose_points[0] > 0 and b.pose_vertices[0] > 0
    _, counts, placed = _draw(gl_ctx, reps, dl)
    m, n = int(b.pose_vertices[0]), int(b.pose_points[0])
    assert counts["poses"] == 1 and counts["placed_points"] == n and counts["posed_vertices"] == m
    lo, scale = pose_box(rep)
    t = rep.tree
    fr = full_frames.SkinnedFrames.of(rep.base)
    f = float(b.pose[0])
    assert f == int(f)  # pose sharing at the baked rows ("key"): an exact row
    P = fr.positions(np.array([int(f)]))[0]
    tol = 1.5 * scale / 65535.0 + 1e-6
    got_v = _decode(placed[:m], lo, scale)
    np.testing.assert_allclose(got_v["p0"], P[t.vorder[:m]], atol=tol)
    h = t.octree
    c = np.asarray(h.indices, np.int64)[np.asarray(h.tri[:n], np.int64)]
    bary = np.asarray(h.bary[:n], np.float64)
    S = (1 - bary[:, 0:1] - bary[:, 1:2]) * P[c[:, 0]] + bary[:, 0:1] * P[c[:, 1]] + bary[:, 1:2] * P[c[:, 2]]
    got_s = _decode(placed[m:m + n], lo, scale)
    np.testing.assert_allclose(got_s["p0"], S, atol=3 * tol)
    # normals: the filtered normal turned with the shading frame (lod.points.follow.frame_coordinates)
    _, nrm = __import__("sim.skinning", fromlist=["skin"]).skin(
        dataclasses.replace(walker.mesh, positions=rep.base.positions, normals=rep.base.normals,
                            joints=rep.base.joints, weights=rep.base.weights),
        np.concatenate([fr.jt[int(f)].astype(np.float64), np.tile([[[0, 0, 0, 1.0]]], (fr.jt.shape[1], 1, 1))], 1))
    Nv = (np.stack([1 - bary[:, 0] - bary[:, 1], bary[:, 0], bary[:, 1]], 1)[:, :, None] * nrm[c]).sum(1)
    Nv /= np.linalg.norm(Nv, axis=1, keepdims=True)
    cos = (got_s["n0"] * Nv).sum(1)
    lnrm = np.asarray(t.lnrm[:n], np.float64)
    facing = lnrm[:, 2] > 0.99  # filtered normal along the shading normal: turned onto it
    assert facing.sum() > n // 4 and np.median(cos[facing]) > np.cos(np.radians(3.0))


def test_copies_in_one_pose_place_it_once(gl_ctx, walker, cache):
    """12 copies at 12 times near 3 baked rows: pose sharing ("key") places 3 poses, and the image is that of
    every copy drawn at its own exact time once those times are the rows (pose_rate 0: one pose per time)."""
    reps, sel = _build(walker, cache)
    dt = 1.0 / 30.0
    times = np.repeat([3 * dt, 10 * dt, 20 * dt], 4) + np.tile([-0.3, -0.1, 0.1, 0.3], 3) * dt
    st = _state(times, xs=np.linspace(-3.0, 3.0, 12))
    cam = Camera.look_at((0.0, 1.5, 9.0), (0.0, 0.9, 0.0), fov_y=45.0, near=0.05, far=200.0)
    dl = sel.select(st, cam, (256, 128))
    assert dl.stats["point_poses"] == 3
    img, counts, _ = _draw(gl_ctx, reps, dl, (256, 128))
    assert counts["poses"] == 3
    sel.pose_rate = 0.0
    try:
        assert sel.select(st, cam, (256, 128)).stats["point_poses"] == 12  # exact: a pose per copy
        on_rows = _state(np.repeat([3 * dt, 10 * dt, 20 * dt], 4), xs=np.linspace(-3.0, 3.0, 12))
        dl0 = sel.select(on_rows, cam, (256, 128))
    finally:
        sel.pose_rate = "key"
    img0, counts0, _ = _draw(gl_ctx, reps, dl0, (256, 128))
    assert counts0["poses"] == 3 and counts0["placed_points"] == counts["placed_points"]
    np.testing.assert_array_equal(img, img0)


def test_rounds_under_a_small_storage_limit_draw_the_same_pixels(gl_ctx, walker, cache):
    """A storage limit below the frame's placed samples places the poses in rounds (each pass poses and places
    its round again): the same image."""
    reps, sel = _build(walker, cache)
    st = _state(np.linspace(0.0, 1.0, 9, endpoint=False), xs=np.linspace(-4.0, 4.0, 9))
    cam = Camera.look_at((0.0, 1.5, 7.0), (0.0, 0.9, 0.0), fov_y=50.0, near=0.05, far=200.0)
    dl = sel.select(st, cam, (256, 128))
    ref, c_ref, _ = _draw(gl_ctx, reps, dl, (256, 128))
    img, c_img, _ = _draw(gl_ctx, reps, dl, (256, 128), limit=16 * 4000)
    assert c_ref["poses"] == c_img["poses"] >= 5
    assert (np.abs(ref.astype(int) - np.asarray(BG) * 255).max(axis=2) > 3).sum() > 2000
    np.testing.assert_array_equal(img, ref)


def test_close_up_is_the_skinned_mesh_the_baked_poses_are_not(gl_ctx, walker, cache):
    """So close that both traversals end at their leaves' triangles, at a time between baked keyframes: drawn
    from the posed vertices of the skinned animation the triangles are full detail's (to the pose box's unorm16
    quantisation), the per-keyframe-pair octrees' interpolated poses depart from it."""
    reps, sel = _build(walker, cache)
    breps, bsel = pm.build([walker], ["wb"], [30], {"animation": "baked", "keyframes": 4}, cache=cache,
                           progress=False)
    full = build_rep(walker, key="none:w")
    st = _state([11.0 / 30.0])  # a baked row (pose sharing draws rows, "key"), between the 4 baked keyframes
    cam = Camera.look_at((0.0, 1.2, 0.9), (0.0, 1.1, 0.0), fov_y=45.0, near=0.05, far=200.0)
    ref = _draw(gl_ctx, [full], NoLodSelector([full]).select(st, cam, SIZE))[0]
    dl = sel.select(st, cam, SIZE)
    assert dl.stats["points"] == 0 and dl.stats["triangles"] > 0
    img = _draw(gl_ctx, reps, dl)[0]
    bimg = _draw(gl_ctx, breps, bsel.select(st, cam, SIZE))[0]
    assert psnr(img, ref) >= 40.0 and psnr(img, ref) > psnr(bimg, ref) + 5.0, (psnr(img, ref), psnr(bimg, ref))


def test_morph_targets_and_keyframes_follow(gl_ctx, cache):
    """A skinned mesh with animated morph targets (skin ∘ morph in the pose pass) and a flip-book keyframe
    animation (segment interpolation in the pose pass) both draw near full detail."""
    from tiny_characters import tiny_morphed

    from sim.procedural import quadruped

    for ch, t, cam in ((tiny_morphed(), 0.3, Camera.look_at((0.0, 1.5, 5.0), (0.0, 1.5, 0.0), fov_y=50.0)),
                       (pm.keyframed_character(quadruped(900, seed=2), 5), 0.45,
                        Camera.look_at((0.0, 1.2, 4.5), (0.0, 0.9, 0.0), fov_y=50.0))):
        reps, sel = _build(ch, cache)
        assert getattr(reps[0], "follow", False)
        full = build_rep(ch, key="none:x")
        st = _state([t])
        ref = _draw(gl_ctx, [full], NoLodSelector([full]).select(st, cam, SIZE))[0]
        img, counts, _ = _draw(gl_ctx, reps, sel.select(st, cam, SIZE))
        assert counts["poses"] == 1 and psnr(img, ref) >= 30.0, (ch.name, psnr(img, ref))


def test_gl_points_reference_path_draws_the_placed_samples(gl_ctx, walker, cache):
    """The GL_POINTS reference path splats the same placed samples: its silhouette matches the compute path's."""
    from image_checks import silhouette_error

    reps, sel = _build(walker, cache)
    cam = Camera.look_at((0.0, 1.1, 12.0), (0.0, 0.95, 0.0), fov_y=45.0, near=0.05, far=200.0)
    dl = sel.select(_state([0.6]), cam, SIZE)
    assert dl.stats["points"] > 0
    a = _draw(gl_ctx, reps, dl)[0]
    for r in reps:
        r.renderer = "gl_points"
    try:
        b = _draw(gl_ctx, reps, dl)[0]
    finally:
        for r in reps:
            r.renderer = "compute"

    def mask(img):
        return np.abs(img.astype(int) - np.round(np.asarray(BG) * 255).astype(int)).max(axis=2) > 2

    assert mask(a).sum() > 200 and silhouette_error(mask(a), mask(b)) <= 2.0


def _posed_jobs_reference(items, add_base):
    """The numpy form posed_job_table replaced (render/points/follow.py before): filter, gather, stack, prefix."""
    parts = []
    for jobs, slot, base_of_pose, row0 in items:
        j = np.asarray(jobs, np.int64).reshape(-1, 3)
        base = np.asarray(base_of_pose, np.int64)[np.asarray(slot, np.int64)[j[:, 0]]]
        keep = (j[:, 2] > 0) & (base >= 0)
        first = j[keep, 1] + (base[keep] if add_base else 0)
        parts.append(np.stack([first, j[keep, 2], row0 + j[keep, 0]], 1))
    j = np.concatenate(parts) if parts else np.zeros((0, 3), np.int64)
    pre = np.concatenate([[0], np.cumsum(j[:, 1])[:-1]]) if j.shape[0] else np.zeros(0, np.int64)
    return np.concatenate([j, pre[:, None]], axis=1).astype(np.uint32)


@pytest.mark.parametrize("add_base", [True, False])
def test_posed_job_table_is_the_numpy_form(add_base):
    """The follow points' job tables (numba, render.points.jobs.posed_job_table) equal the numpy form they
    replaced: jobs with no items and jobs whose pose is not placed this round left out, the rest in order with
    the pose's base (point jobs), the batch's first row and the exclusive prefix; empty inputs give (0, 4); more
    than 2**32 items is refused."""
    from render.points.jobs import posed_job_table

    rng = np.random.default_rng(5)
    items = []
    for b in range(3):
        n, P, k = 50 + 10 * b, 7, 200
        jobs = np.stack([rng.integers(0, n, k), rng.integers(0, 1000, k), rng.integers(0, 4, k)], 1)
        items.append((jobs.astype([np.uint32, np.int64, np.int32][b]), rng.integers(0, P, n),
                      np.where(rng.random(P) < 0.3, -1, rng.integers(0, 10_000, P)), 1000 * b))
    got = posed_job_table(items, add_base)
    want = _posed_jobs_reference(items, add_base)
    assert got.dtype == np.uint32 and got.shape == want.shape and 0 < got.shape[0] < 600
    np.testing.assert_array_equal(got, want)
    assert posed_job_table([], add_base).shape == (0, 4)
    assert posed_job_table([(np.zeros((0, 3), np.int64), np.zeros(0), np.zeros(1), 0)], add_base).shape == (0, 4)
    big = (np.array([[0, 0, 2 ** 31], [0, 0, 2 ** 31]], np.int64), np.zeros(1, np.int64), np.zeros(1, np.int64), 0)
    with pytest.raises(ValueError, match="2\\*\\*32"):
        posed_job_table([big], add_base)
