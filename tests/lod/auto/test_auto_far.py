"""Mode auto with the far tier (``[lod] far_pixels``, lod/far): the far agents are taken before the choice,
the rest keep their state indices, and the cost model prices far splats on their own."""
import numpy as np

from lod.auto import build as ab
from lod.auto import cost_model as cm
from lod.far.select import FarBatch
from lod.full.mode import NoLodSelector
from lod.view import Camera
from sim.procedural import humanoid
from sim.state import CrowdState


def _crowd(n=240, seed=2):
    rng = np.random.default_rng(seed)
    st = CrowdState.empty(n)
    st.position[:, 0] = rng.uniform(-40.0, 40.0, n)
    st.position[:, 2] = rng.uniform(-1500.0, -10.0, n)
    st.heading[:] = rng.uniform(-3, 3, n)
    st.anim_time[:] = rng.uniform(0, 1, n)
    return st


def test_auto_takes_far_agents_first_and_keeps_agent_ids():
    ch = humanoid(600, 7)
    st = _crowd()
    cam = Camera.look_at((0.0, 3.0, 0.0), (0.0, 0.0, -100.0), fov_y=40.0, near=0.5, far=3000.0)
    size = (320, 240)
    lists = {}
    for far_px in (0.0, 2.0):
        reps, sel = ab.build([ch], ["w"], [30], {"far_pixels": far_px, "candidates": "triangles", "adapt": False},
                             progress=False, cache=False)
        assert any(r.kind == "far" for r in reps) == (far_px > 0)
        lists[far_px] = sel.select(st, cam, size)
    without, with_far = lists[0.0], lists[2.0]
    fars = [b for b in with_far.batches if isinstance(b, FarBatch)]
    assert len(fars) == 1 and with_far.stats["far"] == fars[0].n_instances > 0
    far_ids = set(fars[0].instance_ids.tolist())
    near_ids = [int(i) for b in with_far.batches if not isinstance(b, FarBatch) for i in b.instance_ids]
    assert not far_ids & set(near_ids) and len(set(near_ids)) == len(near_ids)
    # the same agents are drawn in all (the near ones by the same representation as without the tier)
    all_ids = sorted(i for b in without.batches for i in b.instance_ids.tolist())
    culled_only = NoLodSelector([_rep(ch)]).select(st, cam, size)  # every agent in the frustum, once
    assert sorted(near_ids + list(far_ids)) == all_ids == sorted(i for b in culled_only.batches
                                                                for i in b.instance_ids.tolist())
    near_by_id = {int(i): b.rep for b in with_far.batches if not isinstance(b, FarBatch) for i in b.instance_ids}
    before = {int(i): b.rep for b in without.batches for i in b.instance_ids}
    assert all(before[i] == r for i, r in near_by_id.items())
    assert with_far.stats["instances"] == without.stats["instances"]
    assert with_far.stats["auto"]["representations"]["far"] == len(far_ids)


def _rep(ch):
    from lod.full.reps import build_rep

    return build_rep(ch, 30)


def test_cost_features_price_far_splats_apart():
    b = FarBatch("far:w", 0, np.arange(1000, dtype=np.int32), np.zeros((1000, 4), np.float32), points=1000,
                 words=np.zeros(1000, np.uint32))
    from lod.drawlist import DrawList

    dl = DrawList(np.zeros(3), np.eye(4, dtype=np.float32), np.eye(4, dtype=np.float32), (320, 240), [b],
                  {"points": 1000, "far": 1000, "triangles": 0})
    x = cm.features(dl, extended=True)
    names = cm.ONLINE_FEATURES
    assert x[names.index("far")] == 1000
    assert x[names.index("points")] == 0 and x[names.index("instances")] == 0 and x[names.index("splat_pixels")] == 0
