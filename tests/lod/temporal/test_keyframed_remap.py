"""The keyframed selection after agents left and entered (``KeyframedSelector.remap_agents``, sim.population):
between keyframes, the agents that stayed keep the representation their keyframes chose, under their new
indices; entered agents are selected on the spot; nobody who left is drawn and nobody is drawn twice outside a
transition."""
import numpy as np
import pytest

from lod.chains import mode as tm
from lod.temporal import selection as ks
from lod.view import Camera
from sim.population import resize
from sim.procedural import humanoid
from sim.state import CrowdState

SIZE = (320, 240)


@pytest.fixture(scope="module")
def chain():
    reps, _ = tm.build([humanoid(1500, 3)], ["h"], [30], {"poe": 1.0, "levels": 5}, cache=False)
    return reps


def _crowd(n, seed):
    rng = np.random.default_rng(seed)
    st = CrowdState.empty(n)
    st.position[:] = np.c_[rng.uniform(-20, 20, n), np.zeros(n), rng.uniform(-90, 0, n)]
    st.heading[:] = rng.uniform(0, 6.28, n)
    st.anim_time[:] = rng.uniform(0, 1, n)
    return st


def _levels(dl):
    """{agent index: (rep, level)} of the unfaded rows, and every drawn index."""
    out, every = {}, []
    for b in dl.batches:
        ids = np.asarray(b.instance_ids, np.int64)
        if ids.size and ids[0] < 0:
            continue
        every.append(ids)
        if b.fade is None:
            for i in ids:
                out[int(i)] = (b.rep, int(getattr(b, "level", -1)))
    return out, np.concatenate(every) if every else np.zeros(0, np.int64)


def test_remap_keeps_the_keyframes_of_the_agents_that_stayed(chain):
    st = _crowd(40, 1)
    near = Camera.from_yaw_pitch(np.array([0.0, 1.7, 25.0]), 0.0, -0.05, 50.0, 0.1, 500.0)
    far = Camera.from_yaw_pitch(np.array([0.0, 1.7, 90.0]), 0.0, -0.05, 50.0, 0.1, 500.0)
    sel = ks.KeyframedSelector(tm.TrianglesSelector(chain), n=4, mode="current")
    first, _ = _levels(sel.select(st, near, SIZE))  # a keyframe, seen from near
    ids_before = st.ids.copy()
    keep = np.flatnonzero(np.arange(40) % 3 != 0)  # a third leave
    src = resize(st, keep, _crowd(5, 2))
    sel.remap_agents(src, st)
    dl = sel.select(st, far, SIZE)  # between keyframes, from far away
    levels, every = _levels(dl)
    assert np.array_equal(np.sort(every), np.arange(st.n))  # only agents alive, each once
    fresh, _ = _levels(tm.TrianglesSelector(chain).select(st, far, SIZE))  # what a selection now would choose
    differ = 0
    for new_i, old_i in enumerate(src):
        if old_i >= 0:
            assert levels[new_i] == first[old_i]  # its keyframe's choice, under its new index
            assert st.ids[new_i] == ids_before[old_i]
            differ += levels[new_i] != fresh[new_i]
        else:
            assert levels[new_i] == fresh[new_i]  # entered: selected on the spot
    assert differ > 5  # the keyframes' choices are not what a selection now makes: the remap carried them
    assert dl.stats["fresh"] == 5
