"""The speed-ups of #19's speed figures give the same results as the code they shortcut:
line-of-sight pre-test, the projection's clear-move exit, resolve's dense grid, the goals kernel."""
import math

import numpy as np
import pytest

from sim.avoidance.neighbors import sight_blocked, sight_may_block
from sim.avoidance.resolve import RESOLVE_DENSE_FACTOR, RESOLVE_TARGET
from sim.goals import Goals, kinematic_numpy, kinematic_step
from sim.grid import build_grid, build_grid_numpy
from sim.obstacles import ObstacleSet, _project_kernel, polygon_boxes, project_numpy
from sim.state import CrowdState


def room(origin=(0.0, 0.0)):
    """A 40 m square room of four thin wall boxes (bounding circles contain the whole room) and a pillar."""
    ox, oz = origin
    boxes = [{"center": [ox, oz + 20.0], "size": [40.0, 0.2]}, {"center": [ox, oz - 20.0], "size": [40.0, 0.2]},
             {"center": [ox + 20.0, oz], "size": [0.2, 40.0]}, {"center": [ox - 20.0, oz], "size": [0.2, 40.0]},
             {"center": [ox + 3.0, oz + 1.0], "size": [1.0, 4.0], "yaw": 30.0}]
    return ObstacleSet(circles=[{"center": [ox - 5.0, oz + 4.0], "radius": 0.7}], boxes=boxes)


@pytest.mark.parametrize("origin", [(0.0, 0.0), (1e6, -1e6)])
def test_sight_pretest_is_exact(origin):
    """Wherever sight_may_block says no, no segment shorter than the reach is blocked."""
    obs = room(origin)
    rng = np.random.default_rng(3)
    reach = 1.8
    p = rng.uniform(-21.0, 21.0, (3000, 2)) + origin
    ang = rng.uniform(0, 2 * math.pi, 3000)
    ln = rng.uniform(0, reach * (1 - 1e-9), 3000)
    q = p + np.stack([np.cos(ang), np.sin(ang)], 1) * ln[:, None]
    free = blocked = 0
    pbox = polygon_boxes(obs.verts, obs.pstart)
    for (px, pz), (qx, qz) in zip(p, q):
        may = sight_may_block(px, pz, reach, obs.circles, obs.verts, obs.pstart, obs.pbound, pbox)
        b = sight_blocked(px, pz, qx, qz, obs.circles, obs.verts, obs.pstart, obs.pbound, pbox)
        assert may or not b
        free += not may
        blocked += b
    assert free > 1500 and blocked > 20  # the pre-test spares most agents; some segments do cross walls


@pytest.mark.parametrize("origin", [(0.0, 0.0), (1e6, -1e6)])
def test_project_clear_move_exit_matches_reference(origin):
    obs = room(origin)
    rng = np.random.default_rng(5)
    n = 4000
    prev = rng.uniform(-20.5, 20.5, (n, 2)) + origin
    step = rng.normal(0, 0.4, (n, 2))
    pos = np.zeros((n, 3))
    pos[:, 0], pos[:, 2] = prev[:, 0] + step[:, 0], prev[:, 1] + step[:, 1]
    vel = rng.normal(0, 1.0, (n, 3))
    p1, v1 = pos.copy(), vel.copy()
    _project_kernel(p1, v1, prev, True, obs.circles, obs.verts, obs.pstart, obs.pbound, 0.3,
                    polygon_boxes(obs.verts, obs.pstart))
    p2, v2 = pos.copy(), vel.copy()
    project_numpy(obs, p2, v2, prev, 0.3)
    np.testing.assert_allclose(p1, p2, rtol=0, atol=1e-9)
    np.testing.assert_allclose(v1, v2, rtol=0, atol=1e-9)
    assert np.isfinite(p1).all()


def test_resolve_grid_stays_dense_at_one_agent_per_square_metre():
    n = 10_000
    pos = np.zeros((n, 3))
    g = np.arange(n)
    pos[:, 0], pos[:, 2] = (g % 100) * 1.0, (g // 100) * 1.0
    cell = 2 * 0.2 * RESOLVE_TARGET
    grid = build_grid(pos, cell, dense_factor=RESOLVE_DENSE_FACTOR)
    ref = build_grid_numpy(pos, cell, dense_factor=RESOLVE_DENSE_FACTOR)
    assert grid.dense and not build_grid(pos, cell).dense
    np.testing.assert_array_equal(grid.order, ref.order)
    np.testing.assert_array_equal(grid.start, ref.start)


@pytest.mark.parametrize("loop", [True, False])
@pytest.mark.parametrize("origin", [(0.0, 0.0), (1e6, -1e6)])
def test_goals_kernel_matches_numpy_reference(loop, origin):
    rng = np.random.default_rng(7)
    n = 500
    ox, oz = origin
    cfg = {"paths": [[[ox, oz], [ox + 10.0, oz]], [[ox + 5.0, oz + 5.0], [ox - 5.0, oz + 5.0], [ox, oz - 8.0]]],
           "arrive_radius": 1.5, "speed": 1.3, "loop": loop}
    st = CrowdState.empty(n)
    st.position[:, 0] = rng.uniform(-12, 12, n) + ox
    st.position[:, 2] = rng.uniform(-12, 12, n) + oz
    st.position[:3, [0, 2]] = [ox + 10.0, oz]  # exactly on a waypoint
    a, b = Goals(cfg, st), Goals(cfg, st)
    sa = CrowdState.empty(n)
    for f in ("position", "velocity", "heading"):
        getattr(sa, f)[:] = getattr(st, f)
    for _ in range(60):
        kinematic_step(a, st, 0.1)
        kinematic_numpy(b, sa, 0.1)
        np.testing.assert_array_equal(a.target, b.target)
        np.testing.assert_array_equal(st.position, sa.position)  # same arithmetic: bit-identical
        np.testing.assert_array_equal(st.velocity, sa.velocity)
        np.testing.assert_allclose(st.heading, sa.heading, rtol=0, atol=1e-12)
    assert np.isfinite(st.position).all()


@pytest.mark.parametrize("origin", [0.0, 1e6])
def test_finalize_kernel_matches_numpy_reference(origin):
    from sim.avoidance.effect import finalize_kernel, finalize_numpy

    rng = np.random.default_rng(11)
    n = 2000
    prev = rng.uniform(-5, 5, (n, 3)) + origin
    v = rng.normal(0, 1, (n, 2))
    vpref = rng.normal(0, 1, (n, 2))
    v[:50] = 0.0  # stopped
    vpref[50:100] = 0.0  # standing
    v[100:150] = -vpref[100:150]  # half turn
    heading = rng.uniform(-math.pi, math.pi, n)
    heading[:20] = math.pi
    rate = rng.uniform(0.5, 1.5, n).astype(np.float32)
    outs = []
    for f in (finalize_kernel, finalize_numpy):
        pos, vel, h, r, base = np.zeros((n, 3)), np.zeros((n, 3)), heading.copy(), rate.copy(), np.empty_like(rate)
        f(pos, vel, h, r, base, prev, vpref, v, 0.05)
        outs.append((pos, vel, h, r, base))
    (p1, v1, h1, r1, b1), (p2, v2, h2, r2, b2) = outs
    np.testing.assert_array_equal(p1, p2)
    np.testing.assert_array_equal(v1, v2)
    np.testing.assert_array_equal(b1, b2)
    np.testing.assert_allclose(r1, r2, rtol=1e-6)
    dh = np.angle(np.exp(1j * (h1 - h2)))
    assert np.abs(dh).max() < 1e-12
    assert np.all((h1 > -math.pi) & (h1 <= math.pi))
    np.testing.assert_array_equal(h1[:50], heading[:50])  # stopped agents keep their heading
