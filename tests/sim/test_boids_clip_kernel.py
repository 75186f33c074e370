"""The boids effect's walk/run switch and animation rate (sim/boids.py _ClipTable.update): the
parallel numba kernel equals the numpy reference bit for bit, on agents that switch both ways,
stand still, play clips without ground speed, or have out-of-range character / clip indices."""
from types import SimpleNamespace

import numpy as np
import pytest

from sim.boids import _ClipTable
from sim.state import CrowdState


def _characters():
    def clip(speed, duration):
        return SimpleNamespace(speed=speed, duration=duration)

    a = SimpleNamespace(clips={"walk": clip(1.3, 1.1), "run": clip(3.1, 0.7), "idle": clip(0.0, 2.0)})
    b = SimpleNamespace(clips={"walk": clip(1.0, 0.9)})  # no run clip: no switching
    return [a, b]


@pytest.mark.parametrize("advance", [False, True])
def test_clip_kernel_equals_the_numpy_reference(advance):
    rng = np.random.default_rng(3)
    n = 50_000
    table = _ClipTable(_characters(), {"walk_clip": "walk", "run_clip": "run", "run_speed": 2.5,
                                       "run_hysteresis": 0.3})
    st = CrowdState.empty(n)
    st.character[:] = rng.integers(-1, 3, n)  # -1 and 2: outside the table
    st.clip[:] = rng.integers(-1, 4, n)
    sp = rng.choice([0.0, 1.0, 2.3, 2.5, 2.6, 4.0], n) + rng.uniform(-0.05, 0.05, n)
    h = rng.uniform(-3, 3, n)
    st.velocity[:, 0], st.velocity[:, 2] = sp * np.sin(h), sp * np.cos(h)
    st.velocity[:7] = 0.0  # standing still
    st.anim_time[:] = rng.uniform(-3.0, 30.0, n)
    st.anim_rate[:] = rng.uniform(0.5, 2.0, n).astype(np.float32)
    ref = CrowdState.empty(n)
    for name in ("character", "clip", "velocity", "anim_time", "anim_rate"):
        getattr(ref, name)[:] = getattr(st, name)
    orig = st.clip.copy()
    table.update(st, 1 / 30, advance)
    table.update_numpy(ref, 1 / 30, advance)
    np.testing.assert_array_equal(st.clip, ref.clip)
    walk_to_run = (orig == 0) & (st.clip == 1) & (st.character == 0)
    run_to_walk = (orig == 1) & (st.clip == 0) & (st.character == 0)
    assert walk_to_run.sum() > 100 and run_to_walk.sum() > 100
    np.testing.assert_array_equal(st.anim_time, ref.anim_time)
    np.testing.assert_array_equal(st.anim_rate, ref.anim_rate)
    assert st.clip.dtype == ref.clip.dtype
