"""sim.animation effect: clip time advance and wrap, numba kernel vs numpy reference."""
import numpy as np
import pytest

from sim import animation
from sim.character import KeyframedCharacter, SkinnedCharacter
from sim.clip import Clip
from sim.keyframes import from_meshes
from sim.mesh import Mesh
from sim.params import ParamError, validate
from sim.state import CrowdState
from sim.world import World


def characters():
    a = SkinnedCharacter("a", None, None, {"walk": Clip("walk", 1.0), "run": Clip("run", 0.5),
                                           "once": Clip("once", 2.0, loop=False)})
    b = SkinnedCharacter("b", None, None, {"still": Clip("still", 0.0)})
    m = Mesh(np.eye(3, dtype=np.float32), np.array([[0, 1, 2]], np.uint32))
    kf = KeyframedCharacter("k", {"wave": from_meshes("wave", [0.0, 0.5], [m, m], loop=True, duration=1.5)})
    return [a, b, kf]


def world(n=8, rate=1.0, seed=0):
    st = CrowdState.empty(n)
    rng = np.random.default_rng(seed)
    st.character[:] = rng.integers(0, 3, n)
    st.clip[:] = np.where(st.character == 0, rng.integers(0, 3, n), 0)
    st.anim_time[:] = rng.uniform(0, 3, n)
    st.anim_rate[:] = rng.uniform(0.5, 2.0, n).astype(np.float32)
    w = World(st, characters(), seed=seed)
    w.install("animation", validate(animation.PARAMS, {"rate": rate}, "effects[0]"))
    return w


def test_params_schema():
    assert validate(animation.PARAMS, {}, "e") == {"rate": 1.0}
    with pytest.raises(ParamError, match="e.rate"):
        validate(animation.PARAMS, {"rate": -1.0}, "e")


def test_table_durations_and_loops():
    t = animation.ClipTable(characters())
    np.testing.assert_allclose(t.duration, [[1.0, 0.5, 2.0], [0, 0, 0], [1.5, 0, 0]])
    assert t.loop[0, 2] == False  # noqa: E712
    d, lp = t.gather(np.array([0, 2, 5, -1]), np.array([1, 0, 0, 0]))
    np.testing.assert_allclose(d, [0.5, 1.5, 0.0, 0.0])


def test_step_advances_and_wraps():
    w = world(1)
    st = w.state
    st.character[0], st.clip[0], st.anim_time[0], st.anim_rate[0] = 0, 0, 0.9, 1.0
    w.step(0.25)
    assert st.anim_time[0] == pytest.approx(0.15)
    st.clip[0] = 2  # one-shot clip holds its last pose
    st.anim_time[0] = 1.9
    w.step(0.25)
    assert st.anim_time[0] == 2.0
    st.character[0], st.clip[0] = 2, 0  # keyframed: duration 1.5
    st.anim_time[0] = 1.4
    w.step(0.2)
    assert st.anim_time[0] == pytest.approx(0.1)


def test_global_rate_and_negative_rates():
    w = world(1, rate=2.0)
    st = w.state
    st.character[0], st.clip[0], st.anim_time[0], st.anim_rate[0] = 0, 0, 0.1, -1.0
    w.step(0.1)
    assert st.anim_time[0] == pytest.approx(0.9)  # 0.1 - 0.2 wraps to 0.9


def test_zero_duration_invalid_indices_and_nan_give_zero():
    w = world(4)
    st = w.state
    st.character[:] = [1, 0, 7, 0]
    st.clip[:] = [0, 9, 0, 0]
    st.anim_time[:] = [0.3, 0.3, 0.3, np.nan]
    w.step(0.1)
    np.testing.assert_array_equal(st.anim_time, [0, 0, 0, 0])
    st.check_finite()


def test_kernel_matches_reference():
    w = world(5000, rate=1.3, seed=4)
    st = w.state
    table = w.resources["animation"]
    for _ in range(5):
        expect = animation.advance_reference(st.anim_time, st.anim_rate, st.character, st.clip, table, 0.37, 1.3)
        w.step(0.37)
        np.testing.assert_allclose(st.anim_time, expect, rtol=0, atol=1e-12)
        dur, _ = table.gather(st.character, st.clip)
        assert np.all(st.anim_time >= 0) and np.all(st.anim_time <= np.maximum(dur, 0))


def test_empty_state_and_duplicate_install():
    w = world(0)
    w.step(0.1)
    with pytest.raises(ValueError, match="listed twice"):
        w.install("animation", {"rate": 1.0})


def test_table_rebuilt_when_characters_change():
    w = world(2)
    w.characters.append(SkinnedCharacter("c", None, None, {"x": Clip("x", 4.0)}))
    w.state.character[:] = 3
    w.state.clip[:] = 0
    w.state.anim_time[:] = 3.0
    w.state.anim_rate[:] = 1.0
    w.step(0.5)
    np.testing.assert_allclose(w.state.anim_time, 3.5)
