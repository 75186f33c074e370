"""Feet of replayed people (issue 47, item 3; ``sim.replay.feet``, ``sim.replay.planting``): the stance foot's
drift per step, measured from the skinned feet. A straight walk at constant speed does not slide; with the feet as
recorded a clip played at the wrong rate does, and the measure sees it; planted, it does not; the drawn body stays
within MAX_OFFSET of the recording, which the world's state keeps; the bottleneck experiment's figures are held
where they are (scripts/bench_foot_drift.md)."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_replay import PEDESTRIAN, engine_of, write_txt  # noqa: E402

from sim.replay.feet import replay_drifts  # noqa: E402


def straight(tmp_path, speed=1.2, frames=250, feet="planted"):
    rows = [(1, f, speed / 25.0 * f, 0.5) for f in range(frames)] + [(2, f, 0.0, 2.0 + speed / 25.0 * f)
                                                                     for f in range(frames)]
    return engine_of(tmp_path, write_txt(tmp_path / "straight.txt", rows), frames=frames,
                     extra=f'feet = "{feet}"\n')


@pytest.mark.parametrize("feet", ["planted", "recorded"])
def test_a_straight_walk_does_not_slide(tmp_path, feet):
    d = replay_drifts(straight(tmp_path, feet=feet), 250)
    assert d.shape[0] >= 20  # both feet of both walkers, every step
    assert d.max() < (0.001 if feet == "planted" else 0.015), d


def test_a_clip_played_too_fast_slides_and_is_seen(tmp_path, monkeypatch):
    import sim.replay.effect as effect

    orig = effect._clip_speeds
    monkeypatch.setattr(effect, "_clip_speeds", lambda w: 0.5 * orig(w))  # twice the natural rate
    d = replay_drifts(straight(tmp_path, feet="recorded"), 250)
    assert d.shape[0] >= 20 and np.median(d) > 0.08, d  # the foot travels back twice as far as the body goes


def test_a_planted_foot_sets_the_phase_of_a_clip_played_too_fast(tmp_path, monkeypatch):
    """Planted, the stance foot holds and the clip's phase follows the body over it: no step slides."""
    import sim.replay.effect as effect

    orig = effect._clip_speeds
    monkeypatch.setattr(effect, "_clip_speeds", lambda w: 0.5 * orig(w))
    d = replay_drifts(straight(tmp_path), 250)
    assert d.shape[0] >= 20 and d.max() < 0.005, d


def test_planted_people_are_drawn_near_their_recording_which_the_state_keeps(tmp_path):
    """The world's state sits on the recording; the drawn state is it plus offsets of at most MAX_OFFSET (in the
    floor plane only), zero for nobody planted; everything finite."""
    from sim.replay.planting import MAX_OFFSET

    eng = straight(tmp_path, speed=1.5)
    rec = eng.world.resources["replay"].tracks[0].recording
    moved = 0.0
    for k in range(120):
        eng.step()
        st, drawn = eng.world.state, eng.drawn_state()
        person = eng.world.resources["replay"].person
        want = rec.at(person, rec.first_frame + k)
        np.testing.assert_allclose(st.position[:, [0, 2]], want, atol=1e-9)
        d = drawn.position - st.position
        assert np.isfinite(drawn.position).all() and (d[:, 1] == 0).all()
        assert np.hypot(d[:, 0], d[:, 2]).max() <= MAX_OFFSET + 1e-9
        moved = max(moved, float(np.abs(d).max()))
        assert drawn.ids is st.ids or np.array_equal(drawn.ids, st.ids)
    assert moved > 0.0  # the plant did move the drawn body


def test_the_bottleneck_experiments_drift_stays_where_it_was_measured():
    from crowd.engine import Engine
    from crowd.scene import load_scene, missing_data

    path = Path(__file__).resolve().parents[2] / "scenes" / "replay_bottleneck.toml"
    if missing_data(path):
        pytest.skip(f"no shared pedestrian data at {PEDESTRIAN}")
    eng = Engine(load_scene(path).with_overrides(size=(64, 36)), quiet=True)
    d = replay_drifts(eng, 1657)
    assert d.shape[0] > 500
    # planted: measured median 0.0 cm, 95th percentile 9.5 cm (as recorded: 5.7 cm and 25 cm)
    assert np.median(d) < 0.01 and np.percentile(d, 95) < 0.12 and (d > 0.05).mean() < 0.12
