"""sim.routing.follow: the routed goals step (numba, one pass) against its numpy reference."""
import numpy as np
import pytest
from routing_testutil import U_BOUNDS, U_BOXES


@pytest.fixture(autouse=True, scope="module")
def one_thread():
    import numba

    prev = numba.get_num_threads()
    numba.set_num_threads(1)
    yield
    numba.set_num_threads(prev)


def world(loop):
    from sim.goals import PARAMS as GOALS
    from sim.obstacles import PARAMS as OBSTACLES
    from sim.params import validate
    from sim.routing.effect import PARAMS as ROUTING
    from sim.routing.effect import with_walls
    from sim.state import CrowdState
    from sim.world import World

    rng = np.random.default_rng(4)
    st = CrowdState.empty(60)
    st.position[:, 0] = rng.uniform(-14.0, -5.0, 60)
    st.position[:, 2] = rng.uniform(-9.0, 9.0, 60)
    w = World(state=st, characters=[], seed=0)
    routing = validate(ROUTING, {"bounds": U_BOUNDS, "clearance": 0.25}, "routing")
    w.install("obstacles", with_walls(routing, validate(OBSTACLES, {"agent_radius": 0.25, "boxes": U_BOXES}, "o")))
    w.install("routing", routing)
    paths = [[[10.0, 0.0], [0.0, 0.0]], [[0.0, 8.5], [10.0, -6.0], [-12.0, 0.0]], [[-3.0, 2.0]]]
    w.install("goals", validate(GOALS, {"paths": paths, "loop": loop, "speed": 1.3, "arrive_radius": 1.0}, "g"))
    return w


@pytest.mark.parametrize("loop", [True, False])
def test_routed_kinematic_step_equals_reference(loop):
    from sim.goals import kinematic_numpy, kinematic_step

    a, b = world(loop), world(loop)
    ga, gb = a.resources["goals"], b.resources["goals"]
    advanced = np.zeros(a.state.n, bool)
    for _ in range(120):
        before = ga.target.copy()
        kinematic_step(ga, a.state, 0.25)
        kinematic_numpy(gb, b.state, 0.25)
        np.testing.assert_allclose(a.state.position, b.state.position, rtol=0, atol=1e-9)
        np.testing.assert_allclose(a.state.velocity, b.state.velocity, rtol=0, atol=1e-9)
        np.testing.assert_allclose(a.state.heading, b.state.heading, rtol=0, atol=1e-9)
        assert np.array_equal(ga.target, gb.target)
        advanced |= ga.target != before
    assert advanced.sum() > (10 if loop else 0)  # waypoints were reached and advanced


def test_routed_desired_velocity_equals_reference():
    a, b = world(False), world(False)
    for _ in range(3):
        va = a.resources["goals"].desired_velocity(a.state)
        vb = b.resources["goals"].routed_velocity_numpy(b.state)
        np.testing.assert_allclose(va, vb, rtol=0, atol=1e-12)
        assert np.allclose(np.hypot(va[:, 0], va[:, 1]), 1.3)
