"""sim.instancing: hierarchical instantiation (Wand & Straßer §3.6)."""
import math

import numpy as np
import pytest

from sim.instancing import Hierarchy, Instancing, install, parse_levels
from sim.params import ParamError
from sim.placement import concat_states
from sim.state import CrowdState
from sim.world import World

LEVELS = [
    {"layout": "list", "children": [{"position": [0, 0, 0]}, {"position": [0.5, 0, 0.2], "yaw": 30, "scale": 0.9}],
     "phase_step": 0.3},
    {"layout": "grid", "nx": 3, "nz": 2, "spacing": [2.0, 3.0], "yaw": 10.0, "phase_step": 0.45},
    {"layout": "tiers", "rows": 4, "seats_per_row": 5, "row_rise": 0.5, "row_depth": 0.9, "arc": 120.0,
     "radius": 20.0, "phase_step": 0.7},
    {"layout": "list", "children": [{"position": [0, 0, 0]}, {"position": [100, 0, 0], "yaw": 180}]},
]


def naive(h: Hierarchy):
    """Nested loops composing 4x4 matrices, outermost index first."""
    def mat(t, yaw, s):
        c, sn = math.cos(yaw), math.sin(yaw)
        m = np.eye(4)
        m[:3, :3] = s * np.array([[c, 0, sn], [0, 1, 0], [-sn, 0, c]])
        m[:3, 3] = t
        return m

    out = []

    def rec(level, m, yaw, off):
        if level < 0:
            out.append((m[:3, 3].copy(), yaw, np.cbrt(np.linalg.det(m[:3, :3])), off % h.period))
            return
        lv = h.levels[level]
        for i in range(lv.count):
            rec(level - 1, m @ mat(lv.translation[i], lv.yaw[i], lv.scale[i]), yaw + lv.yaw[i],
                off + lv.time_offset[i])

    rec(h.depth - 1, mat(h.origin, h.yaw, 1.0), h.yaw, 0.0)
    return out


def test_counts_and_flatten_match_naive_nested_loops():
    h = Hierarchy(parse_levels(LEVELS), character=3, clip=1, period=1.1, origin=[1e6, 2.0, -5.0], yaw=0.3)
    assert h.counts == [2, 6, 20, 2] and h.n_instances == 480 and h.depth == 4
    st = h.flatten()
    ref = naive(h)
    assert st.n == len(ref)
    np.testing.assert_allclose(st.position, np.array([r[0] for r in ref]), atol=1e-8)
    yaw = np.array([r[1] for r in ref])
    np.testing.assert_allclose(np.exp(1j * st.heading), np.exp(1j * yaw), atol=1e-12)
    np.testing.assert_allclose(st.scale, np.array([r[2] for r in ref]), rtol=1e-6)
    np.testing.assert_allclose(st.anim_time, np.array([r[3] for r in ref]), atol=1e-9)
    assert (st.character == 3).all() and (st.clip == 1).all()
    st.check_finite()
    assert h.flatten() is st  # cached
    assert h.flatten(copy=True) is not st


def test_node_transforms_per_level():
    h = Hierarchy(parse_levels(LEVELS), period=1.0)
    for depth, n in [(0, 480), (1, 240), (2, 40), (3, 2), (4, 1)]:
        t, yaw, s, off = h.node_transforms(depth)
        assert t.shape == (n, 3) and yaw.shape == s.shape == off.shape == (n,)
    with pytest.raises(ValueError):
        h.node_transforms(5)
    # node k at depth d owns instances [k m, (k + 1) m): its transform composed with the
    # subtree's local transforms gives theirs
    assert [h.instances_per_node(d) for d in range(5)] == [1, 2, 12, 240, 480]
    t2, yaw2, s2, _ = h.node_transforms(2)
    inner = Hierarchy(h.levels[:2], period=1.0)  # the subtree, at the origin
    ti, yi, si, _ = inner.node_transforms(0)
    from sim.instancing import compose
    k = 17
    tc, yc, sc = compose(t2[k], yaw2[k], s2[k], ti, yi, si)
    st = h.flatten()
    np.testing.assert_allclose(tc, st.position[k * 12:(k + 1) * 12], atol=1e-9)
    np.testing.assert_allclose(np.exp(1j * yc), np.exp(1j * st.heading[k * 12:(k + 1) * 12]), atol=1e-12)


def test_phase_offsets_periodic():
    h = Hierarchy(parse_levels([{"layout": "grid", "nx": 10, "nz": 1, "phase_step": 0.3}]), period=1.0)
    np.testing.assert_allclose(h.levels[0].time_offset, np.mod(np.arange(10) * 0.3, 1.0))


def test_tiers_straight_and_curved():
    lv = parse_levels([{"layout": "tiers", "rows": 3, "seats_per_row": 4, "row_rise": 0.5, "row_depth": 1.0,
                        "seat_spacing": 0.6}])
    h = Hierarchy(lv)
    st = h.flatten()
    np.testing.assert_allclose(st.position[4:8, 1], 0.5)  # row 1 is one step higher
    np.testing.assert_allclose(st.position[4:8, 2], -1.0)  # and one step back
    np.testing.assert_allclose(np.diff(st.position[:4, 0]), 0.6)
    h = Hierarchy(parse_levels([{"layout": "tiers", "rows": 2, "seats_per_row": 5, "arc": 90.0, "radius": 10.0}]))
    st = h.flatten()
    r = np.hypot(st.position[:, 0], st.position[:, 2])
    np.testing.assert_allclose(r[:5], 10.0)
    # every seat faces the centre
    f = np.stack([np.sin(st.heading), np.cos(st.heading)], 1)
    to_c = -st.position[:, [0, 2]] / r[:, None]
    np.testing.assert_allclose(f, to_c, atol=1e-12)


def test_large_hierarchy_is_cheap_and_installs():
    h = Hierarchy(parse_levels([{"layout": "grid", "nx": 2, "nz": 2},
                                {"layout": "grid", "nx": 150, "nz": 150, "spacing": [4, 4]}]))
    st = h.flatten(copy=True)
    assert st.n == 90_000
    st.hierarchy = h
    w = World(state=concat_states([st]), characters=[])
    w.install("instancing", {})
    inst = w.resources["instancing"]
    assert isinstance(inst, Instancing) and inst.hierarchy is h and inst.n_instances == 90_000
    assert w.schedule.steps == []  # costs nothing per frame


def test_instancing_without_hierarchy_is_an_error():
    w = World(state=CrowdState.empty(3), characters=[])
    with pytest.raises(ParamError, match="hierarchy"):
        install(w, {})


def test_parse_levels_errors():
    with pytest.raises(ParamError):
        parse_levels([])
    with pytest.raises(ParamError, match=r"levels\[0\].children"):
        parse_levels([{"layout": "list", "children": []}])
    with pytest.raises(ParamError, match="at most"):
        parse_levels([{"layout": "grid", "nx": 100_000, "nz": 100_000}])
