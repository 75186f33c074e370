"""sim.boids / sim.grid / sim.obstacles / sim.goals: behaviour, limits, degenerate inputs,
numba kernels vs numpy references."""
import math

import numpy as np
import pytest

from sim import boids, goals, obstacles
from sim.boids import PARAMS, param_vector, step_kernel, step_numpy
from sim.clip import Clip
from sim.character import SkinnedCharacter
from sim.config import BOIDS_CANDIDATE_FACTOR
from sim.grid import build_grid, build_grid_numpy
from sim.params import ParamError, validate
from sim.state import CrowdState
from sim.world import World


def flock(n, seed=0, extent=20.0, speed=1.0, origin=(0.0, 0.0)):
    rng = np.random.default_rng(seed)
    st = CrowdState.empty(n)
    st.position[:, 0] = origin[0] + rng.uniform(0, extent, n)
    st.position[:, 2] = origin[1] + rng.uniform(0, extent, n)
    st.velocity[:, [0, 2]] = rng.normal(0, speed, (n, 2))
    st.heading[:] = rng.uniform(-math.pi, math.pi, n)
    return st


def make_world(st, effects, characters=()):
    w = World(state=st, characters=list(characters), seed=1)
    for name, cfg in effects:
        from sim.systems import effect_module

        w.install(name, validate(effect_module(name).PARAMS, cfg, f"effects.{name}"))
    return w


def run(w, steps, dt=1 / 30, check=True):
    for _ in range(steps):
        w.step(dt)
        if check:
            w.state.check_finite()


# ------------------------------------------------------------------ params
def test_params_validate_and_reject_bad_values():
    cfg = validate(PARAMS, {"radius": 3.0}, "effects[0]")
    assert cfg["radius"] == 3.0 and cfg["max_neighbors"] == 32
    for bad in ({"radius": 0.0}, {"radius": -1.0}, {"max_speed": 0.0}, {"max_neighbors": 0},
                {"bounds": [0, 0, 1]}, {"bounds": [1, 0, 0, 1]}, {"bogus": 1}):
        with pytest.raises(ParamError):
            validate(PARAMS, bad, "effects[0]")
    with pytest.raises(ParamError, match="circles"):
        validate(obstacles.PARAMS, {"circles": [{"center": [0, 0], "radius": -1}]}, "effects[1]")
    with pytest.raises(ParamError, match="polygons"):
        validate(obstacles.PARAMS, {"polygons": [{"points": [[0, 0], [1, 1]]}]}, "effects[1]")
    with pytest.raises(ParamError, match="paths"):
        validate(goals.PARAMS, {"paths": [[[0, 0], [1]]]}, "effects[2]")


# ------------------------------------------------------------------ grid
@pytest.mark.parametrize("far", [False, True])
def test_grid_matches_numpy_reference_and_is_stable(far):
    st = flock(500, seed=3)
    if far:  # a few agents very far away: hashed buckets
        st.position[:3, 0] += [1e5, -4e4, 7e4]
    g, r = build_grid(st.position, 2.0), build_grid_numpy(st.position, 2.0)
    assert g.dense == (not far)
    for a in ("cx", "cz", "key", "start", "order"):
        np.testing.assert_array_equal(getattr(g, a), getattr(r, a))
    # stable: within a bucket, agents in increasing index order
    for b in range(g.n_buckets):
        seg = g.order[g.start[b]:g.start[b + 1]]
        assert np.all(np.diff(seg) > 0)
        assert np.all(g.key[seg] == b)


def test_extreme_spread_and_single_agent():
    st = flock(50, seed=1)
    st.position[0, 0] = 1e13  # cells per axis capped; agents still find their neighbours
    st.position[1] = st.position[0] + [0.5, 0.0, 0.0]
    g = build_grid(st.position, 2.0)
    assert not g.dense and g.dims[0] <= 2 ** 30
    P = param_vector({})
    a = [st.position.copy(), st.velocity.copy(), st.heading.copy()]
    b = [st.position.copy(), st.velocity.copy(), st.heading.copy()]
    step_kernel(*a, P, 32, 0.05)
    step_numpy(*b, P, 32, 0.05)
    for x, y in zip(a, b):
        np.testing.assert_allclose(x, y, rtol=1e-15, atol=1e-9)
    # the far pair repel each other: their relative velocity along x grows
    assert a[1][1, 0] - a[1][0, 0] > st.velocity[1, 0] - st.velocity[0, 0]
    w = make_world(flock(1), [("boids", {})])
    run(w, 10)


def test_grid_empty_and_single():
    g = build_grid(np.zeros((0, 3)), 1.0)
    assert g.order.size == 0
    g = build_grid(np.zeros((1, 3)), 1.0)
    assert list(g.order) == [0]
    with pytest.raises(ValueError):
        build_grid(np.zeros((1, 3)), 0.0)


# ------------------------------------------------------ kernel vs reference
@pytest.mark.parametrize("case", ["dense", "hashed", "coincident", "capped", "bounded_ext"])
def test_kernel_matches_numpy_reference(case):
    st = flock(300, seed=7, extent=15.0)
    cfg, ext, nb = {}, None, 32
    if case == "hashed":
        st.position[:4, 2] += [3e4, -2e4, 5e4, 1e5]
    if case == "coincident":
        st.position[:20] = st.position[0]
        st.velocity[:10] = 0.0
    if case == "capped":
        st.position[:, [0, 2]] *= 0.1
        nb = 3
    if case == "bounded_ext":
        cfg = {"bounds": [0.0, 0.0, 10.0, 10.0], "bounds_margin": 2.0}
        ext = np.random.default_rng(1).normal(0, 3, (st.n, 3))
    P = param_vector(validate(PARAMS, cfg | {"max_neighbors": nb}, "b"))
    a = [st.position.copy(), st.velocity.copy(), st.heading.copy()]
    b = [st.position.copy(), st.velocity.copy(), st.heading.copy()]
    for _ in range(15):
        step_kernel(*a, P, nb, 0.05, ext=ext)
        step_numpy(*b, P, nb, 0.05, ext=ext)
    for x, y in zip(a, b):
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-9)
        assert np.isfinite(x).all()


# ------------------------------------------------------------- behaviour
def test_hundred_agents_at_one_point_separate():
    st = CrowdState.empty(100)
    st.position[:] = [3.0, 0.0, -2.0]
    w = make_world(st, [("boids", {"separation_radius": 1.0, "cruise_speed": 0.0, "w_cohesion": 0.0})])
    run(w, 150)
    p = w.state.position[:, [0, 2]]
    d = np.sqrt(((p[:, None] - p[None]) ** 2).sum(-1)) + np.eye(100) * 1e9
    assert d.min() > 0.05
    assert np.median(d.min(1)) > 0.5


def test_head_on_pair_resolves_without_deadlock():
    st = CrowdState.empty(2)
    st.position[:, 0] = [-6.0, 6.0]
    st.velocity[:, 0] = [1.4, -1.4]
    st.heading[:] = [math.pi / 2, -math.pi / 2]
    w = make_world(st, [("boids", {"cruise_speed": 1.4, "w_cohesion": 0.0, "w_alignment": 0.0})])
    dmin = 1e9
    for _ in range(450):  # 15 s
        w.step(1 / 30)
        w.state.check_finite()
        dmin = min(dmin, float(np.linalg.norm(w.state.position[0] - w.state.position[1])))
    assert w.state.position[0, 0] > 3.0 and w.state.position[1, 0] < -3.0  # passed each other
    assert dmin > 0.3
    # symmetric: the pair stays point-symmetric about the origin
    np.testing.assert_allclose(w.state.position[0], -w.state.position[1], atol=1e-9)


def test_far_from_origin_flock_matches_flock_at_origin():
    a, b = flock(200, seed=5), flock(200, seed=5)
    off = np.array([1e6, 0.0, -1e6])
    b.position += off
    wa, wb = make_world(a, [("boids", {})]), make_world(b, [("boids", {})])
    run(wa, 100), run(wb, 100)
    ra = wa.state.position - wa.state.position.mean(0)
    rb = wb.state.position - wb.state.position.mean(0)
    assert np.abs(ra - rb).max() < 1e-3
    np.testing.assert_allclose(wa.state.velocity, wb.state.velocity, atol=1e-6)


@pytest.mark.parametrize("dt", [1 / 240, 1 / 60, 1 / 30, 1 / 10])
def test_dt_sweep_bounded(dt):
    st = flock(400, seed=2, extent=10.0, speed=3.0)
    w = make_world(st, [("boids", {"max_speed": 2.0, "max_accel": 4.0, "max_turn_rate": 90.0})])
    prev = np.arctan2(w.state.velocity[:, 0], w.state.velocity[:, 2])
    for k in range(int(round(3.0 / dt))):
        w.step(dt)
        sp = np.hypot(w.state.velocity[:, 0], w.state.velocity[:, 2])
        assert sp.max() <= 2.0 + 1e-9
        if k > 0:  # turn-rate limit (speeds were already clamped)
            ang = np.arctan2(w.state.velocity[:, 0], w.state.velocity[:, 2])
            turn = np.abs(np.angle(np.exp(1j * (ang - prev))))
            assert turn.max() <= math.radians(90.0) * dt + 1e-9
            prev = ang
        else:
            prev = np.arctan2(w.state.velocity[:, 0], w.state.velocity[:, 2])
    w.state.check_finite()
    assert np.abs(w.state.position).max() < 100.0


def test_zero_velocity_agents():
    st = CrowdState.empty(50)
    st.position[:, 0] = np.arange(50) * 3.0
    st.heading[:] = 0.7
    w = make_world(st, [("boids", {"cruise_speed": 0.0})])
    run(w, 30)
    assert np.all(w.state.velocity == 0.0) and np.all(w.state.heading == 0.7)
    st = CrowdState.empty(50)
    st.position[:, 0] = np.arange(50) * 3.0
    st.heading[:] = 0.7
    w = make_world(st, [("boids", {"cruise_speed": 1.0, "w_alignment": 0.0, "w_cohesion": 0.0})])
    run(w, 60)  # standing agents start walking along their heading
    v = w.state.velocity
    np.testing.assert_allclose(np.arctan2(v[:, 0], v[:, 2]), 0.7, atol=1e-9)
    np.testing.assert_allclose(w.state.heading, 0.7, atol=1e-9)


def test_agents_outside_the_world_return():
    st = flock(40, seed=4, extent=5.0)
    st.position[:20, 0] += 80.0
    st.position[20:, 2] -= 60.0
    w = make_world(st, [("boids", {"bounds": [-20.0, -20.0, 20.0, 20.0], "bounds_margin": 4.0})])
    run(w, 30 * 90)
    p = w.state.position
    assert (np.abs(p[:, 0]) <= 20.0).all() and (np.abs(p[:, 2]) <= 20.0).all()


def test_ten_thousand_agents_in_one_cell_finish_a_step():
    rng = np.random.default_rng(0)
    st = CrowdState.empty(10_000)
    st.position[:, [0, 2]] = rng.uniform(0.0, 0.5, (10_000, 2))
    w = make_world(st, [("boids", {"radius": 2.0, "max_neighbors": 16})])
    w.step(1 / 30)
    w.state.check_finite()
    g = w.resources["boids"].grid
    assert g.n_buckets >= 1 and int(np.diff(g.start).max()) == 10_000
    assert BOIDS_CANDIDATE_FACTOR * 16 < 10_000  # the cap is what keeps this fast


def test_obstacle_never_penetrated_deeper_than_one_step():
    dt, vmax, r = 1 / 30, 3.0, 0.4
    for shape in ({"circles": [{"center": [10.0, 0.0], "radius": 2.0}]},
                  {"boxes": [{"center": [10.0, 0.0], "size": [4.0, 4.0], "yaw": 30.0}]},
                  {"polygons": [{"points": [[8.0, -3.0], [12.0, -3.0], [12.0, 3.0], [10.0, 0.5], [8.0, 3.0]]}]}):
        st = CrowdState.empty(9)
        st.position[:, 2] = np.linspace(-1.0, 1.0, 9)
        st.velocity[:, 0] = vmax
        st.heading[:] = math.pi / 2
        w = make_world(st, [("boids", {"max_speed": vmax, "cruise_speed": 10.0, "w_cruise": 100.0,
                                       "max_accel": 50.0, "w_separation": 0.0, "w_cohesion": 0.0,
                                       "w_alignment": 0.0, "w_avoid": 0.0, "radius": 0.01,
                                       "separation_radius": 0.01}),
                            ("obstacles", shape | {"agent_radius": r, "strength": 0.0})])
        obs = w.resources["obstacles"]
        for _ in range(200):
            w.step(dt)
            w.state.check_finite()
            d, _, _ = obs.sdf(w.state.position[:, 0], w.state.position[:, 2])
            assert (r - d).max() <= vmax * dt + 1e-9
            assert d.min() >= r - 1e-6  # in fact pushed out completely
        if "circles" in shape:  # head-on at the centre: held in front (the others slide around)
            assert w.state.position[4, 0] == pytest.approx(10.0 - 2.0 - r, abs=1e-5)


def test_thin_wall_is_not_tunnelled_at_large_steps():
    # 5 cm wall, 10 m/s at dt = 0.1 s: 1 m per step, 20 x the wall thickness
    st = CrowdState.empty(5)
    st.position[:, 0] = np.linspace(-3.0, -1.0, 5)
    st.position[:, 2] = np.linspace(-2.0, 2.0, 5)
    st.velocity[:, 0] = 10.0
    st.heading[:] = math.pi / 2
    w = make_world(st, [("boids", {"max_speed": 10.0, "cruise_speed": 10.0, "w_cruise": 10.0, "max_accel": 100.0,
                                   "w_separation": 0.0, "w_cohesion": 0.0, "w_alignment": 0.0, "w_avoid": 0.0}),
                        ("obstacles", {"boxes": [{"center": [0.0, 0.0], "size": [0.05, 40.0]}],
                                       "agent_radius": 0.3, "strength": 0.0})])
    for _ in range(50):
        w.step(0.1)
        w.state.check_finite()
        assert (w.state.position[:, 0] <= -0.325 + 1e-5).all()


def test_obstacle_force_field_steers_around():
    st = CrowdState.empty(1)
    st.velocity[0, 0] = 1.4
    st.position[0, 2] = 0.3
    st.heading[:] = math.pi / 2
    w = make_world(st, [("boids", {"cruise_speed": 1.4}),
                        ("obstacles", {"circles": [{"center": [8.0, 0.0], "radius": 1.5}]}),
                        ("goals", {"paths": [[[20.0, 0.0]]], "loop": False})])
    run(w, 30 * 25)
    assert w.state.position[0, 0] > 17.0  # went around to the goal


def test_sdf_kernel_matches_numpy_reference():
    obs = obstacles.ObstacleSet(
        circles=[{"center": [0.0, 0.0], "radius": 1.0}],
        boxes=[{"center": [5.0, 5.0], "size": [2.0, 1.0], "yaw": 45.0}],
        polygons=[{"points": [[-5.0, -5.0], [-2.0, -5.0], [-2.0, -2.0], [-3.5, -4.0], [-5.0, -2.0]]}])
    rng = np.random.default_rng(0)
    x, z = rng.uniform(-8, 8, 2000), rng.uniform(-8, 8, 2000)
    d, nx, nz = obs.sdf(x, z)
    rd, rnx, rnz = obstacles.sdf_numpy(obs, x, z)
    np.testing.assert_allclose(d, rd, atol=1e-12)
    np.testing.assert_allclose(nx, rnx, atol=1e-12)
    np.testing.assert_allclose(nz, rnz, atol=1e-12)
    np.testing.assert_allclose(np.hypot(nx, nz), 1.0, atol=1e-12)
    assert obs.sdf(np.array([0.0]), np.array([0.0]))[0][0] == -1.0
    assert obs.sdf(np.array([5.0]), np.array([5.0]))[0][0] == pytest.approx(-0.5)


# ------------------------------------------------------------------ goals
def test_goals_waypoints_loop_with_and_without_boids():
    path = [[10.0, 0.0], [10.0, 10.0], [0.0, 10.0], [0.0, 0.0]]
    for effects in ([("goals", {"paths": [path], "speed": 1.5})],
                    [("boids", {"max_speed": 2.0}), ("goals", {"paths": [path], "speed": 1.5})]):
        st = CrowdState.empty(1)
        w = make_world(st, effects)
        g = w.resources["goals"]
        visited = set()
        for _ in range(30 * 60):
            w.step(1 / 30)
            visited.add(int(g.target[0]))
        w.state.check_finite()
        assert visited == {0, 1, 2, 3}


def test_goals_attractor_pulls():
    st = CrowdState.empty(5)
    st.position[:, 0] = np.arange(5) * 2.0 + 5.0
    w = make_world(st, [("boids", {"cruise_speed": 0.0}),
                        ("goals", {"attractors": [{"center": [0.0, 0.0], "radius": 30.0, "strength": 2.0}]})])
    run(w, 90)
    assert (w.state.position[:, 0] < np.arange(5) * 2.0 + 5.0).all()


# --------------------------------------------------------------- animation
def test_anim_rate_follows_speed_and_walk_run_switch_keeps_phase():
    ch = SkinnedCharacter("h", None, None, {"walk": Clip("walk", 1.0, speed=1.25),
                                            "run": Clip("run", 0.6, speed=3.5)})
    st = CrowdState.empty(1)
    st.anim_time[:] = 0.25  # phase 1/4 of walk
    st.velocity[0, 2] = 1.0
    w = make_world(st, [("boids", {"cruise_speed": 1.0, "run_speed": 2.5, "run_hysteresis": 0.3})], [ch])
    w.step(1 / 30)
    assert w.state.clip[0] == 0
    sp = math.hypot(w.state.velocity[0, 0], w.state.velocity[0, 2])
    assert w.state.anim_rate[0] == pytest.approx(sp / 1.25, rel=1e-6)
    # no animation effect: boids advances the time by distance / stride
    assert w.state.anim_time[0] == pytest.approx(0.25 + sp / 1.25 / 30, rel=1e-6)
    # speed up past run_speed: switch to run, phase fraction kept
    eff = w.resources["boids"]
    eff.P[param_index("cruise_speed")] = 3.0
    eff.P[param_index("max_speed")] = 4.0
    clips = []
    for _ in range(120):
        before = (w.state.clip[0], w.state.anim_time[0])
        w.step(1 / 30)
        clips.append(int(w.state.clip[0]))
        if w.state.clip[0] != before[0]:
            frac0 = (before[1] % 1.0) / 1.0
            sp = math.hypot(w.state.velocity[0, 0], w.state.velocity[0, 2])
            frac1 = (w.state.anim_time[0] - sp / 3.5 / 30) % 0.6 / 0.6
            assert frac1 == pytest.approx(frac0, abs=1e-6)
    assert clips[-1] == 1
    # hysteresis: 2.4 m/s (between run_speed - hysteresis and run_speed) keeps running
    eff.P[param_index("cruise_speed")] = 2.4
    run(w, 120)
    assert w.state.clip[0] == 1
    eff.P[param_index("cruise_speed")] = 1.0
    run(w, 120)
    assert w.state.clip[0] == 0


def param_index(name):
    return boids._P[name]


def test_empty_world_steps():
    w = make_world(CrowdState.empty(0), [("boids", {}), ("obstacles", {"circles": [{"center": [0, 0], "radius": 1}]}),
                                         ("goals", {"paths": [[[1, 1]]]})])
    run(w, 3)


def test_goals_assign_per_group_and_character():
    from sim.placement import concat_states

    a, b = CrowdState.empty(3), CrowdState.empty(2)
    b.character[:] = 1
    st = concat_states([a, b])
    paths = [[[10.0, 0.0]], [[-10.0, 0.0]]]
    for how, want in (("group", [0, 0, 0, 1, 1]), ("character", [0, 0, 0, 1, 1]), ("cycle", [0, 1, 0, 1, 0])):
        w = make_world(concat_states([a, b]), [("goals", {"paths": paths, "assign": how})])
        assert list(w.resources["goals"].path) == want
    assert st.groups == [(0, 3), (3, 2)]


def test_clip_coupling_ignores_other_clips_and_bad_indices():
    ch = SkinnedCharacter("h", None, None, {"walk": Clip("walk", 1.0, speed=1.25),
                                            "run": Clip("run", 0.6, speed=3.5), "idle": Clip("idle", 2.0)})
    st = CrowdState.empty(3)
    st.position[:, 0] = [0.0, 10.0, 20.0]
    st.clip[:] = [2, 7, 0]  # idle, invalid clip, walk
    st.character[:] = [0, 0, 5]  # the third: invalid character
    st.velocity[:, 2] = 3.0
    st.anim_rate[:] = 0.5
    w = make_world(st, [("boids", {"cruise_speed": 3.0, "max_speed": 4.0})], [ch])
    run(w, 30)
    assert list(w.state.clip) == [2, 7, 0]
    np.testing.assert_array_equal(w.state.anim_rate, np.float32(0.5))


def test_obstacle_kernels_match_numpy_references():
    obs = obstacles.ObstacleSet(
        circles=[{"center": [0.0, 0.0], "radius": 1.0}, {"center": [3.0, 0.5], "radius": 0.6}],
        boxes=[{"center": [5.0, 5.0], "size": [2.0, 0.05], "yaw": 30.0}],
        polygons=[{"points": [[-5.0, -5.0], [-2.0, -5.0], [-2.0, -2.0], [-3.5, -4.0], [-5.0, -2.0]]}])
    rng = np.random.default_rng(3)
    n = 3000
    pos = np.zeros((n, 3))
    pos[:, [0, 2]] = rng.uniform(-7, 7, (n, 2))
    vel = np.zeros((n, 3))
    vel[:, [0, 2]] = rng.normal(0, 4, (n, 2))
    args = (0.4, 1.5, 0.8, 6.0, 0.5)
    a, b = np.zeros((n, 3)), np.zeros((n, 3))
    obstacles._steer_kernel(pos, vel, obs.circles, obs.verts, obs.pstart, obs.pbound, *args, a)
    obstacles.steer_numpy(obs, pos, vel, *args, b)
    np.testing.assert_allclose(a, b, atol=1e-9)
    assert np.abs(a).max() > 0
    prev = pos[:, [0, 2]].copy()
    moved = pos.copy()
    moved[:, [0, 2]] += vel[:, [0, 2]] * 0.5  # up to several metres: crosses obstacles
    pa, va = moved.copy(), vel.copy()
    pb, vb = moved.copy(), vel.copy()
    obstacles._project_kernel(pa, va, prev, True, obs.circles, obs.verts, obs.pstart, obs.pbound, 0.4,
                              obstacles.polygon_boxes(obs.verts, obs.pstart))
    obstacles.project_numpy(obs, pb, vb, prev, 0.4)
    np.testing.assert_allclose(pa, pb, atol=1e-9)
    np.testing.assert_allclose(va, vb, atol=1e-9)
    assert not np.allclose(pa, moved)
    d, _, _ = obs.sdf(pa[:, 0], pa[:, 2])
    start, _, _ = obs.sdf(prev[:, 0], prev[:, 1])
    assert d[start > 0.4].min() >= 0.4 - 1e-6  # agents that started clear end clear
