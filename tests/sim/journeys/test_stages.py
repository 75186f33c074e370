"""Stage behaviour: waypoints in order, seeded weighted choices, waiting areas (time, releases, holding
when full), queues (first come first served, one served per service time), exits (agents gone for good),
looping journeys, boids steering; the unreachable-stage check."""
import math

import numpy as np
import pytest

from journeys_testutil import min_gap, placement, run, world_from_text
from sim.journeys.stages import choose, sample_time, uniforms
from sim.journeys.steer import HOLD, IDLE, LEAVING, PENDING, WALK

JOURNEYS = '\n[[effects]]\nname = "journeys"\n'
AVOID = '\n[[effects]]\nname = "avoidance"\n'


def _stage(name, kind, **kw):
    lines = [f'\n[[stages]]\nname = "{name}"\nkind = "{kind}"']
    for k, v in kw.items():
        lines.append(f"{k} = {v}")
    return "\n".join(lines) + "\n"


def test_waypoints_in_order_then_idle_at_the_last():
    text = (JOURNEYS + _stage("a", "waypoint", point="[0.0, 0.0]") + _stage("b", "waypoint", point="[4.0, 0.0]")
            + _stage("c", "waypoint", point="[4.0, 4.0]", radius=0.2)
            + '\n[[journeys]]\nname = "j"\nplacements = [0]\nstages = ["a", "b", "c"]\n' + placement())
    sc, w = world_from_text(text)
    j = w.resources["journeys"]
    seen = [[] for _ in range(w.state.n)]

    def each(w, c):
        for i, s in enumerate(j.stage):
            if not seen[i] or seen[i][-1] != s:
                seen[i].append(int(s))
    run(w, 200, 0.1, each)
    assert all(s == [0, 1, 2] for s in seen)
    assert np.all(j.phase == IDLE)
    d = np.hypot(w.state.position[:, 0] - 4.0, w.state.position[:, 2] - 4.0)
    assert d.max() <= 0.2 + 1e-9


def test_choice_follows_the_weights_and_the_seed():
    text = (JOURNEYS + _stage("x", "waypoint", point="[10.0, 0.0]") + _stage("y", "waypoint", point="[-10.0, 0.0]")
            + '\n[[journeys]]\nname = "j"\nplacements = [0]\nstages = [{x = 3.0, y = 1.0}]\n'
            + placement(rows=20, cols=20, origin=(-5.0, -5.0), spacing=0.5))
    picks = []
    for seed in (1, 1, 2):
        sc, w = world_from_text(text, seed=seed)
        picks.append(w.resources["journeys"].stage.copy())
    assert np.array_equal(picks[0], picks[1]) and not np.array_equal(picks[0], picks[2])
    nx = int(np.sum(picks[0] == 0))
    assert abs(nx - 300) < 3 * math.sqrt(400 * 0.75 * 0.25)
    # a draw depends on (seed, agent id, counter), never on the order agents are processed in
    ids = np.arange(50)
    u = uniforms(7, 1, ids, np.zeros(50))
    assert np.array_equal(uniforms(7, 1, ids[::-1], np.zeros(50)), u[::-1])
    assert np.array_equal(choose((np.array([4, 9]), np.array([0.25, 1.0])), np.array([0.1, 0.3, 0.99])), [4, 9, 9])


def test_time_distributions():
    rng = np.random.default_rng(0)
    u = rng.random((20000, 2))
    assert np.allclose(sample_time({"kind": "fixed", "value": 3.0}, u), 3.0)
    t = sample_time({"kind": "uniform", "min": 2.0, "max": 4.0}, u)
    assert t.min() >= 2.0 and t.max() <= 4.0 and abs(t.mean() - 3.0) < 0.05
    assert abs(sample_time({"kind": "exponential", "mean": 5.0}, u).mean() - 5.0) < 0.15
    t = sample_time({"kind": "normal", "mean": 10.0, "sd": 2.0}, u)
    assert abs(t.mean() - 10.0) < 0.06 and abs(t.std() - 2.0) < 0.06
    assert sample_time({"kind": "normal", "mean": 0.0, "sd": 5.0}, u).min() == 0.0  # truncated at 0


def test_waiting_area_holds_for_the_time_then_lets_go():
    text = (JOURNEYS + AVOID
            + _stage("bench", "wait", slots="[[0.0, 0.0], [1.0, 0.0]]", time=3.0)
            + _stage("away", "waypoint", point="[0.0, 8.0]")
            + '\n[[journeys]]\nname = "j"\nplacements = [0]\nstages = ["bench", "away"]\n'
            + placement(rows=1, cols=4, origin=(-3.0, -4.0), spacing=1.0))
    sc, w = world_from_text(text)
    j = w.resources["journeys"]
    held_from, held_until, pending_max = {}, {}, [0]

    def each(w, c):
        pending_max[0] = max(pending_max[0], int(np.sum(j.phase == PENDING)))
        for i in range(w.state.n):
            if j.phase[i] == HOLD and i not in held_from:
                held_from[i] = w.time
                assert np.hypot(*(w.state.position[i, [0, 2]] - j.stages[0].slots[j.slot[i]])) <= 0.25 + 1e-9
            if j.stage[i] == 1 and i in held_from and i not in held_until:
                held_until[i] = w.time
        assert np.all(np.bincount(j.slot[(j.stage == 0) & (j.slot >= 0)], minlength=2) <= 1)  # one per slot
    run(w, 300, 0.1, each)
    assert pending_max[0] == 2  # four agents, two slots: two hold outside first
    assert len(held_until) == 4
    for i in held_until:
        assert held_until[i] - held_from[i] == pytest.approx(3.0, abs=0.11)


def test_waiting_area_release_times():
    text = (JOURNEYS + _stage("gate", "wait", polygon="[[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]",
                              spacing=0.8, release_at="[6.0, 60.0]")
            + _stage("away", "waypoint", point="[0.0, 8.0]")
            + '\n[[journeys]]\nname = "j"\nplacements = [0]\nstages = ["gate", "away"]\n' + placement())
    sc, w = world_from_text(text)
    j = w.resources["journeys"]
    left_at = {}

    def each(w, c):
        for i in np.flatnonzero(j.stage == 1):
            left_at.setdefault(int(i), w.time)
    run(w, 100, 0.1, each)
    assert len(left_at) == 4 and all(abs(t - 6.0) < 0.11 for t in left_at.values())


def test_queue_serves_first_come_first_served():
    text = (JOURNEYS + AVOID
            + _stage("counter", "queue", line="[[0.0, 0.0], [0.0, -6.0]]", spacing=0.7, time=2.0)
            + _stage("out", "exit", line="[[3.0, -1.0], [3.0, 1.0]]")
            + '\n[[journeys]]\nname = "j"\nplacements = [0]\nstages = ["counter", "out"]\n'
            + placement(rows=2, cols=4, origin=(-6.0, -8.0), spacing=1.0))
    sc, w = world_from_text(text)
    j = w.resources["journeys"]
    assert np.all(j.ticket == -1)  # nobody is in line before reaching its end
    joined, served, gaps = [], [], []

    def each(w, c):
        gaps.append(min_gap(w))
        q = j.stages[0]
        k = int(np.sum((j.stage == 0) & (j.ticket >= 0))) - sum(  # in line before this step
            1 for i in np.flatnonzero((j.stage == 0) & (j.ticket >= 0)) if int(w.state.ids[i]) not in joined)
        end = q.slots[min(k, len(q.slots) - 1)]
        new = [i for i in np.flatnonzero((j.stage == 0) & (j.ticket >= 0)) if int(w.state.ids[i]) not in joined]
        for i in sorted(new, key=lambda i: j.ticket[i]):
            joined.append(int(w.state.ids[i]))
            # joined the line at its end: the next free place, or short of the last one
            d = np.hypot(*(w.state.position[i, [0, 2]] - end)) - max(0, k - (len(q.slots) - 1)) * q.spacing
            assert d <= max(0.25, q.spacing / 2) + 1e-9
        for i in np.flatnonzero((j.stage == 1) & (j.phase == WALK)):
            a = int(w.state.ids[i])
            if a not in [s for s, _ in served]:
                served.append((a, w.time))
    run(w, 400, 0.1, each)
    assert len(served) == 8
    order = [a for a, _ in served]
    assert order == joined  # served in the order they joined the line
    times = np.diff([t for _, t in served])
    assert np.all(times >= 2.0 - 1e-9)  # one at a time, each for the service time
    assert min(gaps) > -0.02 * 0.5  # no two bodies overlap (avoidance's tolerance)
    assert w.state.n == 0  # everyone left through the door


def test_exits_remove_agents_for_good():
    text = (JOURNEYS + _stage("door", "exit", line="[[2.0, -1.0], [2.0, 1.0]]")
            + _stage("pit", "exit", polygon="[[-2.0, 5.0], [2.0, 5.0], [2.0, 7.0], [-2.0, 7.0]]")
            + '\n[[journeys]]\nname = "j"\nplacements = [0]\nstages = [["door", "pit"]]\n'
            + placement(rows=3, cols=3, origin=(-2.0, -1.0), spacing=1.0))
    sc, w = world_from_text(text)
    j = w.resources["journeys"]
    gone, rows = set(), []

    def each(w, c):
        ids = set(w.state.ids.tolist())
        assert not (ids & gone)  # an agent that left never comes back
        leaving = set(w.state.ids[j.phase == LEAVING].tolist())
        rows.append((ids, leaving, c))
    prev = None
    run(w, 150, 0.1, each)
    for ids, leaving, c in rows:
        if prev is not None:
            assert prev[0] - ids == {a for a in prev[0] - ids}  # only removals of agents that were leaving
            assert len(prev[0] - ids) == c["left"]
        prev = (ids, leaving)
    assert w.state.n == 0 and j.exited_by_stage.sum() == 9
    assert set(j.summary()["exits"]) == {"door", "pit"}


def test_loop_journey_cycles():
    text = (JOURNEYS + _stage("a", "waypoint", point="[0.0, 0.0]") + _stage("b", "waypoint", point="[3.0, 0.0]")
            + '\n[[journeys]]\nname = "j"\nplacements = [0]\nloop = true\nstages = ["a", "b"]\n'
            + placement(rows=1, cols=1, origin=(0.0, 0.0)))
    sc, w = world_from_text(text)
    j = w.resources["journeys"]
    laps = []
    run(w, 200, 0.1, lambda w, c: laps.append(int(j.transitions[0])))
    assert laps[-1] >= 5 and j.phase[0] == WALK


def test_boids_steering():
    text = ('\n[[effects]]\nname = "boids"\n' + JOURNEYS + _stage("a", "waypoint", point="[8.0, 0.0]")
            + '\n[[journeys]]\nname = "j"\nplacements = [0]\nstages = ["a"]\n' + placement())
    sc, w = world_from_text(text)
    x0 = w.state.position[:, 0].mean()
    run(w, 60, 0.1)
    assert w.state.position[:, 0].mean() > x0 + 3.0


def test_unreachable_stage_is_named_before_the_run():
    from crowd.errors import SceneError

    walls = ('\n[[effects]]\nname = "obstacles"\nagent_radius = 0.25\nboxes = [\n'
             '  { center = [0.0, 3.0], size = [6.0, 0.4] }, { center = [0.0, -3.0], size = [6.0, 0.4] },\n'
             '  { center = [3.0, 0.0], size = [0.4, 6.4] }, { center = [-3.0, 0.0], size = [0.4, 6.4] },\n]\n')
    text = (JOURNEYS + walls + _stage("goal", "waypoint", point="[10.0, 0.0]")
            + '\n[[journeys]]\nname = "j"\nplacements = [0, 1]\nstages = ["goal"]\n'
            + placement(rows=2, cols=2, origin=(-0.5, -0.5)) + placement(rows=1, cols=3, origin=(-10.0, 5.0)))
    with pytest.raises(SceneError) as e:
        world_from_text(text, path="walled.toml")
    msg = str(e.value)
    assert "\n" not in msg and msg.endswith("walled.toml: journeys[0]: 4 of 7 agents of journey 'j' cannot reach "
                                            "stage 'goal': agents 0, 1, 2, 3 of placement[0] (the first at "
                                            "(-0.50, -0.50))")
    # a gap in the wall: everyone can reach it
    world_from_text(text.replace("{ center = [3.0, 0.0], size = [0.4, 6.4] }",
                                 "{ center = [3.0, 2.0], size = [0.4, 2.4] }"), path="open.toml")
