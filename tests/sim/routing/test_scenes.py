"""The routing scenes (issue 28 acceptance): scenes/u_trap.toml with cfsm and orca (every agent reaches the goal,
no body ever overlaps a wall, routes of agents starting in open space within 3 % of the exact shortest path) and
scenes/square_room.toml (everyone leaves through the door of a square room, no funnel)."""
import math
from pathlib import Path

import numpy as np
import pytest
from routing_testutil import ExactPaths

REPO = Path(__file__).resolve().parents[3]


@pytest.fixture(autouse=True, scope="module")
def one_thread():
    import numba

    prev = numba.get_num_threads()
    numba.set_num_threads(1)
    yield
    numba.set_num_threads(prev)


def build(path, model=None, only=None, drop=("animation",)):
    """A World of the scene (its effects but ``drop``; ``model`` overrides avoidance's, "none" drops it), with
    only the agents ``only`` (indices) if given."""
    from crowd.engine import plan
    from crowd.scene import load_scene
    from sim.state import CrowdState
    from sim.world import World

    sc = load_scene(path)
    pl = plan(sc)
    st = pl.state
    if only is not None:
        st = CrowdState(**{k: v[only].copy() for k, v in st.arrays().items()})
    w = World(state=st, characters=pl.characters, seed=sc.seed)
    w.resources["character_radius"] = [c.radius for c in sc.characters]
    for e in sc.effects:
        if e.name in drop or (e.name == "avoidance" and model == "none"):
            continue
        w.install(e.name, {**e.params, **({"model": model} if e.name == "avoidance" and model else {})})
    return sc, w


def run_to_goal(sc, w, frames=None):
    """Step until every agent has reached its first waypoint; returns (route lengths to the goal: walked plus
    the route left when it counted as reached, reached (bool), the smallest centre-to-wall distance seen)."""
    st, g, obs, r = w.state, w.resources["goals"], w.resources["obstacles"], w.resources["routing"]
    first = g.target.copy()
    L, left = np.zeros(st.n), np.full(st.n, np.nan)
    prev = st.position[:, [0, 2]].copy()
    closest = math.inf
    for _ in range(frames or sc.frames):
        w.step(sc.dt)
        p = st.position[:, [0, 2]].copy()
        going = np.isnan(left)
        L[going] += np.hypot(*(p - prev)[going].T)
        prev = p
        d, _, _ = obs.sdf(p[:, 0].copy(), p[:, 1].copy())
        closest = min(closest, float(d.min()))
        new = going & (g.target != first)
        for i in np.nonzero(new)[0]:
            left[i] = r.distance(int(g.wgoal[first[i]]), p[i:i + 1])[0]
        if not np.isnan(left).any():
            break
    reached = ~np.isnan(left)
    return L + np.nan_to_num(left), reached, closest


U_TRAP = REPO / "scenes" / "u_trap.toml"


@pytest.mark.parametrize("model", ["cfsm", "orca"])
def test_u_trap_every_agent_reaches_the_goal_and_no_body_enters_a_wall(model):
    sc, w = build(U_TRAP, model)
    radius = w.resources["obstacles.agent_radius"]
    _, reached, closest = run_to_goal(sc, w)
    assert reached.all(), f"{(~reached).sum()} of {reached.size} agents never reached the goal"
    assert closest >= radius - 1e-6, closest  # the body (radius 0.25) never overlaps a wall


@pytest.fixture(scope="module")
def exact_u_trap():
    from crowd.engine import plan
    from crowd.scene import load_scene
    from sim.routing.effect import walkable_of

    sc = load_scene(U_TRAP)
    eff = {e.name: e.params for e in sc.effects}
    ex = ExactPaths(walkable_of(eff["routing"], eff["obstacles"]).area, eff["routing"]["clearance"])
    start = plan(sc).state.position[:, [0, 2]]
    goal = tuple(eff["goals"]["paths"][0][0])
    return start, ex, np.array([ex.length(s, goal) for s in start])


def test_u_trap_routes_within_3_percent_of_the_exact_shortest_path(exact_u_trap):
    start, ex, exact = exact_u_trap
    open_space = ex.in_open_space(start)
    assert open_space.sum() >= 35  # the scene's agents start in open space but a few
    sc, w = build(U_TRAP, "none")  # routing alone: goals moves the agents, the walls hold them
    L, reached, _ = run_to_goal(sc, w)
    assert reached.all()
    err = (L - exact) / exact
    assert err[open_space].max() < 0.03 and err[open_space].min() > -0.01, np.round(100 * err, 2)
    assert np.median(err[open_space]) < 0.01


@pytest.mark.parametrize("model", ["cfsm", "orca"])
def test_u_trap_routes_with_each_model_within_3_percent(exact_u_trap, model):
    start, ex, exact = exact_u_trap
    open_space = np.nonzero(ex.in_open_space(start))[0]
    inside = [i for i in open_space if abs(start[i, 0]) < 4 and abs(start[i, 1]) < 4][:3]
    outside = [i for i in open_space if start[i, 0] < -5][:2]
    for i in inside + outside:  # one at a time: the route of the model, not a detour round a neighbour
        sc, w = build(U_TRAP, model, only=[i])
        L, reached, closest = run_to_goal(sc, w)
        assert reached.all() and closest >= 0.25 - 1e-6
        assert abs(L[0] - exact[i]) / exact[i] < 0.03, (i, L[0], exact[i])


def test_square_room_empties_through_its_door():
    sc, w = build(REPO / "scenes" / "square_room.toml")
    st = w.state
    out = np.zeros(st.n, bool)
    t_out = []
    closest = math.inf
    obs = w.resources["obstacles"]
    for f in range(sc.frames):
        w.step(sc.dt)
        x = st.position[:, 0]
        new = ~out & (x > 0.4)
        t_out += [(f + 1) * sc.dt] * int(new.sum())
        out |= new
        if f % 10 == 0:
            d, _, _ = obs.sdf(st.position[:, 0].copy(), st.position[:, 2].copy())
            closest = min(closest, float(d.min()))
        if out.all():
            break
    assert out.all(), f"{(~out).sum()} agents still in the room after {sc.frames * sc.dt:g} s"
    assert closest >= 0.2 - 1e-6
    flow = (len(t_out) - 1) / (t_out[-1] - t_out[0])
    assert 0.7 < flow < 1.3, flow  # 1 m door: JuPedSim gives 0.89 /s on this room (scripts/bench_routing.md)
