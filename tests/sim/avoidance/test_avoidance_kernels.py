"""sim.avoidance kernels (cfsm, orca, resolve) against their plain references, and the model's formulas
on hand-computed cases."""
import math

import numpy as np
import pytest

from sim.avoidance.cfsm import cfsm_velocities
from sim.avoidance.orca import orca_velocities
from sim.avoidance.reference import cfsm_numpy, orca_numpy, resolve_numpy
from sim.avoidance.resolve import resolve
from sim.obstacles import ObstacleSet


def crowd(n, seed, extent=8.0, origin=(0.0, 0.0), coincident=0):
    rng = np.random.default_rng(seed)
    pos = np.zeros((n, 3))
    pos[:, 0] = origin[0] + rng.uniform(0, extent, n)
    pos[:, 2] = origin[1] + rng.uniform(0, extent, n)
    if coincident:
        pos[1:coincident + 1, [0, 2]] = pos[0, [0, 2]]
    radius = rng.uniform(0.18, 0.3, n)
    vpref = rng.normal(0, 1.0, (n, 2))
    vstart = rng.normal(0, 0.8, (n, 2))
    heading = rng.uniform(-math.pi, math.pi, n)
    return pos, radius, vpref, vstart, heading


def obstacle_set():
    return ObstacleSet(circles=[{"center": [3.0, 3.0], "radius": 0.8}],
                       boxes=[{"center": [6.0, 2.0], "size": [0.5, 3.0], "yaw": 20.0}],
                       polygons=[{"points": [[1.0, 6.0], [2.5, 6.5], [1.5, 7.5]]}])


@pytest.mark.parametrize("origin", [(0.0, 0.0), (1e6, -1e6)])
@pytest.mark.parametrize("with_obstacles", [False, True])
def test_cfsm_kernel_matches_reference(origin, with_obstacles):
    pos, radius, vpref, _, heading = crowd(120, 1, origin=origin, coincident=2)
    obs = None
    if with_obstacles:
        o = obstacle_set()
        o.circles[:, :2] += origin
        o.verts += origin
        o.pbound[:, :2] += origin
        obs = o
    for side, v0, cut in [(0.0, 0.0, 3.0), (0.5, 1.2, 2.0), (1.0, 0.0, 0.0)]:
        got, grid, _ = cfsm_velocities(pos, radius, vpref, heading, cutoff=cut, v0=v0, side=side, obstacles=obs)
        want = cfsm_numpy(pos, radius, vpref, heading, cutoff=grid.cell, v0=v0, side=side, obstacles=obs)
        assert np.isfinite(got).all()
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)


def test_cfsm_formulas_on_two_agents():
    """Agent 0 at the origin walking +x, agent 1 standing 1.0 m ahead, radii 0.2: repulsion
    a exp((l - d)/D) on the axis does not turn the direction; speed = (d - l)/T."""
    pos = np.zeros((2, 3))
    pos[1, 0] = 1.0
    radius = np.array([0.2, 0.2])
    vpref = np.array([[1.2, 0.0], [0.0, 0.0]])
    v, _, _ = cfsm_velocities(pos, radius, vpref, np.zeros(2), a=8.0, D=0.1, T=1.0, cutoff=3.0)
    assert v[0, 0] == pytest.approx((1.0 - 0.4) / 1.0, abs=1e-12) and v[0, 1] == 0.0
    assert (v[1] == 0).all()  # standing agents stay
    # neighbour 1.0 m ahead and 0.5 m to the side: outside the corridor (l = 0.4) -> free speed;
    # direction turned away by the repulsion 8 exp((0.4 - d)/0.1)
    pos[1, 2] = 0.5
    v, _, _ = cfsm_velocities(pos, radius, vpref, np.zeros(2), cutoff=3.0)
    d = math.hypot(1.0, 0.5)
    f = 8.0 * math.exp((0.4 - d) / 0.1)
    ux, uz = 1.0 - f * 1.0 / d, -f * 0.5 / d
    s = math.hypot(ux, uz)
    assert v[0] == pytest.approx([1.2 * ux / s, 1.2 * uz / s], abs=1e-12)


def test_cfsm_spacing_of_a_neighbour_in_the_corridor():
    """Agent at (0, 0) walking +x, another standing at (0.7, 0.1), radii 0.2: the direction is turned
    by the repulsion, the neighbour stays in front and within the corridor of half-width l, so the
    speed is (d - l) / T (JuPedSim's GetSpacing / OptimalSpeed)."""
    pos = np.array([[0.0, 0.0, 0.0], [0.7, 0.0, 0.1]])
    radius = np.full(2, 0.2)
    vpref = np.array([[1.34, 0.0], [0.0, 0.0]])
    v, _, _ = cfsm_velocities(pos, radius, vpref, np.zeros(2), cutoff=3.0)
    d = math.hypot(0.7, 0.1)
    f = 8.0 * math.exp((0.4 - d) / 0.1)
    ux, uz = 1.0 - f * 0.7 / d, -f * 0.1 / d
    s = math.hypot(ux, uz)
    ux, uz = ux / s, uz / s
    # in front and within the corridor: spacing d - l
    assert abs(-uz * 0.7 + ux * 0.1) <= 0.4
    speed = min(1.34, max(0.0, (d - 0.4) / 1.0))
    assert v[0] == pytest.approx([ux * speed, uz * speed], abs=1e-12)


@pytest.mark.parametrize("origin", [(0.0, 0.0), (1e6, 1e6)])
def test_orca_kernel_matches_reference(origin):
    pos, radius, vpref, vstart, _ = crowd(60, 2, extent=6.0, origin=origin, coincident=1)
    o = obstacle_set()
    o.circles[:, :2] += origin
    o.verts += origin
    o.pbound[:, :2] += origin
    for obs in (None, o):
        for max_speed in (0.0, 2.0):
            got, _, _ = orca_velocities(pos, radius, vstart, vpref, neighbor_distance=3.0, max_neighbors=8,
                                        max_speed=max_speed, dt=0.05, obstacles=obs)
            want = orca_numpy(pos, radius, vstart, vpref, neighbor_distance=3.0, max_neighbors=8,
                              max_speed=max_speed, dt=0.05, obstacles=obs)
            assert np.isfinite(got).all()
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)


def test_orca_head_on_pair_sidesteps_and_respects_speed_limit():
    pos = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    radius = np.full(2, 0.3)
    v = np.array([[1.0, 0.0], [-1.0, 0.0]])
    out, _, _ = orca_velocities(pos, radius, v, v, time_horizon=2.0, dt=0.05)
    assert np.hypot(out[:, 0], out[:, 1]).max() <= 1.0 + 1e-12
    # reciprocal: opposite sidesteps, and the relative velocity leaves the velocity obstacle
    # (to the 1e-3 m/s symmetry-breaking perturbation of the preferred velocities)
    assert out[0, 1] == pytest.approx(-out[1, 1], abs=1e-2) and abs(out[0, 1]) > 0.05


@pytest.mark.parametrize("with_obstacles", [False, True])
def test_resolve_matches_reference(with_obstacles):
    pos, radius, _, _, _ = crowd(150, 3, extent=5.0, coincident=3)
    obs = obstacle_set() if with_obstacles else None
    a, b = pos.copy(), pos.copy()
    pa = resolve(a, radius, None, obs, iterations=5)
    pb = resolve_numpy(b, radius, None, obs, iterations=5)
    assert pa[0] == pb[0]
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)


def test_resolve_separates_coincident_agents():
    pos = np.zeros((12, 3))
    pos[:, 0] = 5.0
    radius = np.full(12, 0.25)
    passes, worst = resolve(pos, radius, iterations=200)
    d = np.hypot(*(pos[:, None, [0, 2]] - pos[None, :, [0, 2]]).transpose(2, 0, 1))
    d[np.eye(12, dtype=bool)] = np.inf
    assert worst == 0.0 and passes < 200 and d.min() >= 0.5 * (1 - 1e-9)


@pytest.mark.parametrize("model", ["cfsm", "orca"])
def test_resolve_with_the_models_near_flags_equals_the_full_pass(model):
    """The first pass may skip agents without a neighbour within r_i + r_j + 2 vmax dt at the start:
    the result is the same as checking everyone."""
    pos, radius, vpref, vstart, heading = crowd(400, 4, extent=20.0)
    vpref *= 0.5
    pos[:5, [0, 2]] = pos[5, [0, 2]] + np.arange(5)[:, None] * 0.05  # a few overlapping starts
    dt, vmax = 0.05, float(np.hypot(vpref[:, 0], vpref[:, 1]).max())
    near = np.empty(400, np.uint8)
    near_d = 2.0 * vmax * dt * (1 + 1e-9) + 1e-12
    if model == "cfsm":
        v, grid, _ = cfsm_velocities(pos, radius, vpref, heading, near=near, near_d=near_d)
    else:
        v, grid, _ = orca_velocities(pos, radius, vstart, vpref, dt=dt, near=near, near_d=near_d)
    assert 0 < near.sum() < 400
    moved = pos.copy()
    moved[:, 0] += v[:, 0] * dt
    moved[:, 2] += v[:, 1] * dt
    a, b = moved.copy(), moved.copy()
    ra = resolve(a, radius, iterations=20, grid=grid, prev=pos, near=near, near_d=near_d)
    rb = resolve(b, radius, iterations=20, grid=grid, prev=pos)  # same grid, every agent visited
    assert ra == rb
    assert (a == b).all()


def test_cfsm_reproduces_jupedsim_trajectories():
    """data/jupedsim_cfsm_open.npz: 150 agents (radius 0.2) in an open 80 m square walking to an exit
    centred at (35.5, 0), JuPedSim 1.4.2 CollisionFreeSpeedModel with its defaults (desired speed 1.34,
    time gap 1, dt 0.05): positions after 1, 10 and 100 steps. Ours with JuPedSim's 3 m cutoff and no
    side bias gives the same trajectories to rounding."""
    from avoid_testutil import world_from_arrays
    from pathlib import Path

    data = np.load(Path(__file__).parent / "data" / "jupedsim_cfsm_open.npz")
    w = world_from_arrays(data["start"], [
        ("goals", {"paths": [[[35.5, 0.0]]], "loop": False, "speed": 1.34, "arrive_radius": 0.1}),
        ("avoidance", {"radius": 0.2, "v0": 1.34, "side_bias": 0.0, "cutoff": 3.0})])
    for k in range(1, 101):
        w.step(0.05)
        if k in (1, 10, 100):
            err = np.abs(w.state.position[:, [0, 2]] - data[f"step{k}"]).max()
            assert err < 1e-9, f"step {k}: {err:.3g} m from JuPedSim"
