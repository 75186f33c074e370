"""sim.population: compaction with stable ids, the src maps, and the resources that follow a change."""
import hashlib

import numpy as np
import pytest

from sim.population import apply, compose, remap_rows, resize, take_changes
from sim.state import CrowdState
from sim.world import World


def _state(n, seed=0):
    rng = np.random.default_rng(seed)
    st = CrowdState.empty(n)
    st.position[:] = rng.normal(size=(n, 3))
    st.heading[:] = rng.uniform(-3, 3, n)
    st.character[:] = np.arange(n) % 3
    st.anim_time[:] = rng.random(n)
    return st


def test_constant_state_stores_no_ids_and_digest_is_unchanged():
    st = _state(5)
    assert st._ids is None and st.next_id == 5
    assert np.array_equal(st.ids, np.arange(5))
    h = hashlib.sha256()
    for name, a in st.arrays().items():
        h.update(name.encode())
        h.update(np.ascontiguousarray(a).tobytes())
    assert st.digest() == h.hexdigest()  # the digest of a scene whose count never changes is what it was


def test_resize_keeps_order_and_ids_and_gives_fresh_ids():
    st = _state(6)
    before = {k: v.copy() for k, v in st.arrays().items()}
    new = _state(2, seed=9)
    src = resize(st, np.array([0, 2, 5]), new)
    assert st.n == 5
    assert np.array_equal(src, [0, 2, 5, -1, -1])
    assert np.array_equal(st.ids, [0, 2, 5, 6, 7]) and st.next_id == 8
    for name, a in st.arrays().items():
        assert np.array_equal(a[:3], before[name][[0, 2, 5]]), name
        assert np.array_equal(a[3:], new.arrays()[name].astype(a.dtype)), name
        assert a.dtype == before[name].dtype
    # ids are never reused, even after the newest agents left
    resize(st, np.array([0, 1]))
    resize(st, None, _state(1))
    assert np.array_equal(st.ids, [0, 2, 8]) and st.next_id == 9


def test_resize_rejects_bad_keep():
    st = _state(3)
    with pytest.raises(ValueError):
        resize(st, np.array([2, 1]))
    with pytest.raises(ValueError):
        resize(st, np.array([0, 3]))


def test_compose_equals_two_steps():
    a = np.array([0, 2, 3, -1])         # state1 (4) from state0
    b = np.array([3, 1, -1])            # state2 (3) from state1
    assert np.array_equal(compose(a, b), [-1, 2, -1])
    assert compose(None, b) is b and compose(a, None) is a


def test_remap_rows_fills_entered():
    a = np.arange(8.0).reshape(4, 2)
    out = remap_rows(a, np.array([3, -1, 0]), fill=-7.0)
    assert np.array_equal(out, [[6, 7], [-7, -7], [0, 1]])
    assert remap_rows(None, np.array([0])) is None


class _Tracker:
    def __init__(self, n):
        self.value = np.arange(n) * 10
        self.calls = 0

    def remap_agents(self, src, state):
        self.calls += 1
        self.value = remap_rows(self.value, src, fill=-1)
        assert self.value.shape[0] == state.n


def test_apply_tells_resources_and_composes_changes():
    st = _state(4)
    w = World(state=st, characters=[])
    t = w.resources["t"] = _Tracker(4)
    assert apply(w, np.arange(4)) is None and t.calls == 0  # nothing changed: nobody is told
    apply(w, np.array([1, 3]))
    apply(w, None, _state(1))
    assert t.calls == 2 and np.array_equal(t.value, [10, 30, -1])
    src = take_changes(w)
    assert np.array_equal(src, [1, 3, -1])
    assert take_changes(w) is None
    # groups of the initial placements are index ranges: dropped once the count changed
    st.groups = [(0, 2), (2, 1)]
    apply(w, np.array([0, 2]))
    assert st.groups == []


def test_avoidance_follows_a_change():
    """Radii and animation base rates of the agents that stayed are kept, entered agents get their own."""
    from sim.avoidance.effect import PARAMS
    from sim.params import validate

    st = CrowdState.empty(3)
    st.position[:, 0] = [0.0, 2.0, 4.0]
    st.scale[:] = [1.0, 2.0, 3.0]
    w = World(state=st, characters=[], seed=1)
    w.install("avoidance", validate(PARAMS, {}, "effects"))
    w.step(0.1)
    av = w.resources["avoidance"]
    r0 = av.radius.copy()
    av.base_rate = np.array([0.5, 0.6, 0.7], np.float32)
    new = CrowdState.empty(1)
    new.scale[:] = 4.0
    new.anim_rate[:] = 0.9
    new.position[0, 0] = 9.0
    apply(w, np.array([0, 2]), new)
    assert np.allclose(av.radius[:2], r0[[0, 2]])
    assert np.isclose(av.radius[2], r0[0] * 4.0)  # one character: radius ~ scale
    assert np.allclose(av.base_rate, [0.5, 0.7, 0.9])
    w.step(0.1)  # steps on with the new count
    w.state.check_finite()
