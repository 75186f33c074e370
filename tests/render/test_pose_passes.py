"""One pose evaluation per distinct pose and frame (issue 33): on a frame that mixes full detail on the hardware path,
full detail through the compute rasteriser and points that follow the animation, the renderer's ``pose_passes``
(``DrawList.stats``, frames.csv) equals the pose table's distinct poses: the pose cache blends each pose's palette
once, the rasteriser gathers the cache's posed vertices, the follow points read the cache's palettes by slot. Without
pose sharing the count rises (per-copy palettes, the follow points' own evaluations), so the equality can fail. The
follow points' posed vertices from the cache's palettes are those from the joint table (the fallback)."""
import numpy as np
import pytest

from lod.drawlist import DrawList
from lod.full import mode as fm
from lod.points import mode as pm
from lod.points.rep import HierarchyCache
from lod.poses import PoseSharing
from lod.view import Camera
from render.renderer import Renderer
from sim.procedural import humanoid
from sim.state import CrowdState

SIZE = (256, 160)
DT = 1.0 / 30.0
CAM = Camera.look_at((0.0, 1.4, 6.0), (0.0, 0.9, -20.0), fov_y=45.0, near=0.05, far=400.0)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    ch = humanoid(1200, 3)
    cache = HierarchyCache(tmp_path_factory.mktemp("pose_passes"))
    full, full_sel = fm.build([ch], ["w"], [30], {}, progress=False)
    pts, pts_sel = pm.build([ch], ["w"], [30], {"animation": "follow"}, cache=cache, progress=False)
    return full, full_sel, pts, pts_sel


def _state(times, xs, zs):
    st = CrowdState.empty(len(times))
    st.anim_time[:] = times
    st.clip[:] = 0
    st.position[:, 0] = xs
    st.position[:, 2] = zs
    return st


def _frame(built, share: bool = True):
    """The mixed frame: 3 near copies (hardware path) and 24 far ones (sub-pixel triangles: the compute rasteriser)
    at full detail, 8 follow-point copies, poses shared between the two representations and not."""
    full, full_sel, pts, pts_sel = built
    near = _state([3 * DT, 10 * DT, 20 * DT], [-1.0, 0.0, 1.0], [0.0, 0.0, 0.0])
    far = _state(np.repeat([3 * DT, 5 * DT, 7 * DT], 8), np.linspace(-40.0, 40.0, 24), np.full(24, -150.0))
    both = CrowdState.empty(near.n + far.n)
    for name in ("anim_time", "clip", "position"):
        getattr(both, name)[:] = np.concatenate([getattr(near, name), getattr(far, name)])
    dl = full_sel.select(both, CAM, SIZE)
    follow = _state(np.repeat([10 * DT, 12 * DT, 14 * DT, 16 * DT], 2), np.linspace(-3.0, 3.0, 8), np.full(8, -4.0))
    pdl = pts_sel.select(follow, CAM, SIZE)
    out = DrawList(dl.origin, dl.view, dl.proj, dl.size, list(dl.batches) + list(pdl.batches))
    out.options = {**dict(dl.options), **dict(pdl.options)}
    if share:
        ps = PoseSharing()
        ps.register(list(full) + list(pts))
        ps.assign(out)
    return out


def _draw(gl_ctx, built, dl, share: bool = True):
    full, _, pts, _ = built
    with Renderer(SIZE, ctx=gl_ctx, debug=True) as r:
        for rep in list(full) + list(pts):
            r.upload(rep)
        r.pose_sharing = share
        r.draw(dl)
        img = r.read_pixels().copy()
        d = r.uploaded_drawer("points")
        counts = dict(d.last_counts)
        placed = np.frombuffer(d._bufs["follow_placed"].read(), np.uint32).reshape(-1, 4).copy()
        return img, counts, placed, dict(r.raster.last_counts)


def test_one_pose_pass_per_distinct_pose_on_a_mixed_frame(gl_ctx, built):
    dl = _frame(built)
    img, counts, _, raster = _draw(gl_ctx, built, dl)
    assert dl.stats["raster_triangles"] > 0  # the far copies went through the compute rasteriser
    assert counts["poses"] == 4 and counts["placed_points"] > 0  # the follow points placed their four poses
    # one character: the distinct quantised frames of every copy, whichever representation draws it
    frames = np.unique(np.concatenate([np.asarray(b.instance_data)[:, 12] for b in dl.batches]))
    assert dl.stats["poses"] == frames.shape[0] >= 7
    assert dl.stats["pose_passes"] == dl.stats["poses"]
    assert (img.reshape(-1, img.shape[-1])[:, :3] != img[0, 0, :3]).any(axis=1).sum() > 500  # something was drawn


def test_without_pose_sharing_poses_are_evaluated_per_copy(gl_ctx, built):
    """The counter counts: the per-copy palettes of the full-detail copies and the follow points' own evaluations
    from the joint table."""
    dl = _frame(built)
    _, counts, _, _ = _draw(gl_ctx, built, dl, share=False)
    n_full = sum(b.n_instances for b in dl.batches if b.rep.startswith("none:"))
    assert n_full == 27
    assert dl.stats["pose_passes"] >= n_full + counts["poses"] > dl.stats["poses"]


def test_follow_poses_from_the_cache_palettes_match_the_joint_table(gl_ctx, built):
    """The follow points' placed buffer through the cache's palettes (pose table attached) and through their own
    evaluation (no table): the same posed vertices and samples within one unorm16 step of the pose box."""
    _, _, pts, pts_sel = built
    follow = _state(np.repeat([10 * DT, 12 * DT, 14 * DT], 2), np.linspace(-3.0, 3.0, 6), np.full(6, -4.0))
    a = pts_sel.select(follow, CAM, SIZE)
    b = pts_sel.select(follow, CAM, SIZE)
    ps = PoseSharing()
    ps.register(list(pts))
    ps.assign(a)
    img_a, ca, pa, _ = _draw(gl_ctx, built, a)
    img_b, cb, pb, _ = _draw(gl_ctx, built, b)
    assert a.stats["pose_passes"] == a.stats["poses"] == 3
    # no table: the follow passes evaluated the three poses themselves, once per pass that poses them
    assert b.stats["pose_passes"] >= 3 and b.stats.get("poses", 0) == 0
    assert ca["placed_points"] == cb["placed_points"] > 0
    assert pa.shape == pb.shape
    pos_a = np.stack([pa[:, 0] & 0xFFFF, pa[:, 0] >> 16, pa[:, 1] & 0xFFFF], 1).astype(np.int64)
    pos_b = np.stack([pb[:, 0] & 0xFFFF, pb[:, 0] >> 16, pb[:, 1] & 0xFFFF], 1).astype(np.int64)
    assert np.abs(pos_a - pos_b).max() <= 1
    diff = np.abs(img_a.astype(np.int64) - img_b.astype(np.int64))
    assert (diff.max(axis=-1) > 8).sum() <= 2
