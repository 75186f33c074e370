"""Auto chooses the point representation coarser than a hierarchy's root (lod/points/coarse.py)
only within its bound: the point candidate's error (splat + projected keyframe deviation, in
pixels) must be at most poe; then far agents get a handful of points instead of the whole root."""
import numpy as np
import pytest

from lod.auto import build as ab
from lod.auto import candidates as ac
from lod.auto import cost_model
from lod.auto import mode as am
from lod.view import Camera
from sim.procedural import humanoid
from sim.state import CrowdState

SIZE = (320, 240)
MODEL = cost_model.CostModel()


class Free(ac.Candidate):
    """The point candidate at no cost: chosen wherever it is admissible (within the bound)."""

    def __init__(self, inner):
        super().__init__()
        self.inner, self.name, self.reps = inner, inner.name, inner.reps

    def options(self, frame, group):
        o = self.inner.options(frame, group)
        if o is not None:
            o.cost = np.zeros_like(o.cost)
        return o

    def emit(self, *a):
        return self.inner.emit(*a)

    def finish(self, frame, dl):
        self.inner.finish(frame, dl)


@pytest.fixture(scope="module")
def built():
    reps, sel = ab.build([humanoid(1500, 0)], ["h"], [30], {"poe": 2.0, "keyframes": 3}, cache=False, model=MODEL,
                         progress=False, points_params={"animation": "baked"})
    return reps, sel


@pytest.fixture(scope="module")
def follows():
    reps, sel = ab.build([humanoid(1500, 0)], ["h"], [30], {"poe": 2.0}, cache=False, model=MODEL, progress=False)
    return reps, sel


def _far_crowd(n=150):
    rng = np.random.default_rng(7)
    st = CrowdState.empty(n)
    st.position[:, 0] = rng.uniform(-80.0, 80.0, n)
    st.position[:, 2] = rng.uniform(-400.0, -200.0, n)  # 1-3 pixels tall
    st.heading[:] = rng.uniform(-3.0, 3.0, n)
    st.anim_time[:] = rng.uniform(0.0, 1.0, n)
    st.scale[:] = 1.0
    return st


def test_coarse_points_only_within_the_bound(built):
    reps, sel = built
    pts = next(c for c in sel.candidates if c.name == "points")
    st = _far_crowd()
    cam = Camera.look_at((0.0, 8.0, 0.0), (0.0, 0.0, -300.0), fov_y=40.0, near=0.5, far=2000.0)
    prep = next(r for r in reps if getattr(r, "kind", "") == "points")
    root = min(int(h.point_count[0].min()) for h in prep.hierarchies if h.n_nodes and h.child_count[0])
    seen = {}
    for poe in (0.9, 1.0, 2.0, 3.0):
        auto = am.AutoSelector([reps[0]], poe=poe, model=MODEL, candidates=[Free(pts)])
        dl = auto.select(st, cam, SIZE)
        n_pts = dl.stats["auto"]["representations"]["points"]
        seen[poe] = n_pts
        splat = pts.splat_size(poe)
        if n_pts:
            # admissible: the splat (1 px at poe 2) plus the keyframes' deviation within the bound
            assert 1 <= splat <= poe
            drawn = [b for b in dl.batches if getattr(b, "point_jobs", None) is not None]
            per = sum(b.points for b in drawn) / sum(b.n_instances for b in drawn)
            assert per <= root / 3  # a prefix of the root (agents 1-3 pixels tall, 1-pixel splats), not all of it
    # below 2 px the splat alone fills the bound: the keyframe deviation leaves no room, no points
    assert seen[0.9] == seen[1.0] == 0
    # from 2 px the far agents qualify, more of them (nearer ones) as the bound grows
    assert 0 < seen[2.0] <= seen[3.0] and seen[3.0] >= 0.9 * st.n


def test_samples_that_follow_the_animation_qualify_from_one_pixel(follows):
    """No keyframe deviation (the samples follow the skinned animation): a 1-pixel bound admits 1-pixel splats,
    and the far agents draw a prefix of the root (lod/points/coarse.py) at their own poses."""
    reps, sel = follows
    pts = next(c for c in sel.candidates if c.name == "points")
    assert pts.deviation == [0.0] and pts.splat_size(1.0) == 1
    prep = next(r for r in reps if getattr(r, "follow", False))
    root = int(prep.tree.octree.point_count[0, 0])
    st = _far_crowd()
    cam = Camera.look_at((0.0, 8.0, 0.0), (0.0, 0.0, -300.0), fov_y=40.0, near=0.5, far=2000.0)
    seen = {}
    for poe in (0.9, 1.0, 2.0):
        dl = am.AutoSelector([reps[0]], poe=poe, model=MODEL, candidates=[Free(pts)]).select(st, cam, SIZE)
        seen[poe] = dl.stats["auto"]["representations"]["points"]
        drawn = [b for b in dl.batches if getattr(b, "point_jobs", None) is not None]
        if drawn:
            assert sum(b.points for b in drawn) / sum(b.n_instances for b in drawn) <= root / 3
            assert all(b.pose_points.shape == b.pose.shape for b in drawn)  # FollowBatches with their poses
    assert seen[0.9] == 0 and seen[1.0] >= 0.9 * st.n and seen[2.0] >= 0.9 * st.n
