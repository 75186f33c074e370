"""Feet of replayed people (issue 47, item 3; ``sim.replay.feet``): the stance foot's drift per step, measured from
the skinned feet. A straight walk at constant speed does not slide; a clip played at the wrong rate does, and the
measure sees it; the bottleneck experiment's figures are held where they are (the issue's 5 cm is not met: see
scripts/bench_foot_drift.md)."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_replay import PEDESTRIAN, engine_of, write_txt  # noqa: E402

from sim.replay.feet import replay_drifts  # noqa: E402


def straight(tmp_path, speed=1.2, frames=250):
    rows = [(1, f, speed / 25.0 * f, 0.5) for f in range(frames)] + [(2, f, 0.0, 2.0 + speed / 25.0 * f)
                                                                     for f in range(frames)]
    return engine_of(tmp_path, write_txt(tmp_path / "straight.txt", rows), frames=frames)


def test_a_straight_walk_does_not_slide(tmp_path):
    d = replay_drifts(straight(tmp_path), 250)
    assert d.shape[0] >= 20  # both feet of both walkers, every step
    assert d.max() < 0.015, d


def test_a_clip_played_too_fast_slides_and_is_seen(tmp_path, monkeypatch):
    import sim.replay.effect as effect

    orig = effect._clip_speeds
    monkeypatch.setattr(effect, "_clip_speeds", lambda w: 0.5 * orig(w))  # twice the natural rate
    d = replay_drifts(straight(tmp_path), 250)
    assert d.shape[0] >= 20 and np.median(d) > 0.08, d  # the foot travels back twice as far as the body goes


def test_the_bottleneck_experiments_drift_stays_where_it_was_measured():
    from crowd.engine import Engine
    from crowd.scene import load_scene, missing_data

    path = Path(__file__).resolve().parents[2] / "scenes" / "replay_bottleneck.toml"
    if missing_data(path):
        pytest.skip(f"no shared pedestrian data at {PEDESTRIAN}")
    eng = Engine(load_scene(path).with_overrides(size=(64, 36)), quiet=True)
    d = replay_drifts(eng, 1657)
    assert d.shape[0] > 500
    assert np.median(d) < 0.065 and np.percentile(d, 95) < 0.30  # measured 5.7 cm and 25 cm
