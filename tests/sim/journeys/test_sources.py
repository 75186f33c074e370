"""Sources: arrivals at the configured rate (uniform exactly, Poisson within 2 % on average), placement only
where there is room, total / capacity / stop, and the rate kept up after a blocked spawn area frees."""
import math

import numpy as np

from journeys_testutil import min_gap, placement, run, world_from_text
from sim.journeys.sources import Source

AREA = "[[-12.0, -30.0], [-10.0, -30.0], [-10.0, 30.0], [-12.0, 30.0]]"
EXIT = """
[[stages]]
name = "out"
kind = "exit"
polygon = [[20.0, -40.0], [30.0, -40.0], [30.0, 40.0], [20.0, 40.0]]

[[journeys]]
name = "cross"
stages = ["out"]
"""


def _scene(source: str, avoidance=True) -> str:
    eff = '\n[[effects]]\nname = "journeys"\n' + ('\n[[effects]]\nname = "avoidance"\n' if avoidance else "")
    return eff + EXIT + "\n[[sources]]\n" + source + placement(rows=1, cols=1, origin=(0.0, 50.0))


def test_uniform_arrivals_follow_the_rate_exactly():
    sc, w = world_from_text(_scene(f'name = "s"\ncharacter = "p"\njourney = "cross"\nrate = 2.5\n'
                                   f'polygon = {AREA}\n'))
    entered, exited, left, t = [], [], [], []
    run(w, 400, 0.1, lambda w, c: (entered.append(c["entered"]), exited.append(c["exited"]), left.append(c["left"]),
                                   t.append(w.time)))
    cum = np.cumsum(entered)
    expect = np.ceil(np.asarray(t) * 2.5 - 1e-9)  # arrivals at 0, 0.4, 0.8, ... s, each entering at its step's end
    assert np.array_equal(expect, [w.resources["journeys"].sources[0].expected(x) for x in t])
    assert np.array_equal(cum, expect)
    assert abs(cum[-1] / (2.5 * 40.0) - 1.0) < 0.02
    # everyone walks 30-32 m at 1.34 m/s (22.4-23.9 s) and leaves: the exits follow the arrivals by that
    ex = np.cumsum(exited)
    lag = lambda s: np.concatenate([np.zeros(int(round(s / 0.1))), cum])[:cum.size]  # noqa: E731
    assert np.all(ex <= lag(22.3)) and np.all(ex >= lag(24.5))
    assert ex[-1] > 35
    assert w.state.n == 1 + cum[-1] - sum(left)
    assert sum(left) == sum(exited) - int(np.sum(w.resources["journeys"].phase == 4))


def test_poisson_arrivals_match_the_rate_on_average():
    counts = []
    for seed in range(20):
        s = Source({"name": "s", "rate": 5.0, "process": "poisson", "polygon": [[0, 0], [1, 0], [1, 1]]}, 0, seed)
        counts.append(s.arrive(200.0))
    counts = np.asarray(counts, float)
    assert abs(counts.mean() / 1000.0 - 1.0) < 0.02
    assert 0.4 < counts.var() / counts.mean() < 2.0  # Poisson: variance ~ mean
    a = Source({"name": "s", "rate": 5.0, "process": "poisson", "polygon": [[0, 0], [1, 0], [1, 1]]}, 0, 7)
    b = Source({"name": "s", "rate": 5.0, "process": "poisson", "polygon": [[0, 0], [1, 0], [1, 1]]}, 0, 7)
    assert a.arrive(10.0) == b.arrive(10.0)  # deterministic for a seed


def test_poisson_source_places_every_arrival():
    sc, w = world_from_text(_scene(f'name = "s"\ncharacter = "p"\njourney = "cross"\nrate = 3.0\n'
                                   f'process = "poisson"\npolygon = {AREA}\n'), seed=4)
    entered = []
    run(w, 300, 0.1, lambda w, c: entered.append(c["entered"]))
    src = w.resources["journeys"].sources[0]
    assert sum(entered) == src.arrived == src.entered and src.waiting == 0
    assert abs(sum(entered) / 90.0 - 1.0) < 0.25  # one seed: within Poisson noise of 30 s x 3/s


def test_spawn_only_where_there_is_room_and_catch_up():
    """A 2 m spawn line at 4 agents/s with nowhere to go (a waypoint right there, no exit): the line fills
    (no two bodies overlap), arrivals wait; agents that can leave make room, and the count catches up."""
    text = ('\n[[effects]]\nname = "journeys"\n\n[[effects]]\nname = "avoidance"\n'
            '\n[[stages]]\nname = "here"\nkind = "waypoint"\npoint = [0.0, 0.0]\nradius = 0.3\n'
            '\n[[journeys]]\nname = "stay"\nstages = ["here"]\n'
            '\n[[sources]]\nname = "s"\ncharacter = "p"\njourney = "stay"\nrate = 4.0\n'
            'line = [[-1.0, 0.0], [1.0, 0.0]]\n' + placement(rows=1, cols=1, origin=(0.0, 40.0)))
    sc, w = world_from_text(text)
    gaps = []
    run(w, 50, 0.1, lambda w, c: gaps.append(min_gap(w)))
    src = w.resources["journeys"].sources[0]
    assert min(gaps) >= -1e-6  # entered agents never overlap anyone
    assert src.waiting > 0 and src.entered < src.arrived  # the line is full
    assert src.arrived == 20  # arrivals at 0, 0.25, ..., 4.75 s


def test_total_capacity_and_stop():
    base = f'name = "s"\ncharacter = "p"\njourney = "cross"\nrate = 10.0\npolygon = {AREA}\n'
    sc, w = world_from_text(_scene(base + "total = 7\n"))
    run(w, 30, 0.1)
    assert w.resources["journeys"].sources[0].entered == 7
    sc, w = world_from_text(_scene(base + "capacity = 5\n"))
    alive = []
    run(w, 30, 0.1, lambda w, c: alive.append(int(np.sum(w.resources["journeys"].source >= 0))))
    assert max(alive) == 5
    sc, w = world_from_text(_scene(base + "start = 1.0\nstop = 2.0\n"))
    run(w, 40, 0.1)
    assert w.resources["journeys"].sources[0].entered == 11  # t = 1.0, 1.1, ..., 2.0


def test_entered_agents_face_their_first_stage_and_play_their_clip():
    sc, w = world_from_text(_scene(f'name = "s"\ncharacter = "p"\nclip = "run"\njourney = "cross"\nrate = 1.0\n'
                                   f'polygon = {AREA}\n', avoidance=False))
    run(w, 1, 0.1)
    st = w.resources["journeys"]
    i = int(np.flatnonzero(st.source == 0)[0])
    names = w.characters[0].clip_names()
    assert names[int(w.state.clip[i])] == "run"
    # exit polygon east of the spawn area: heading ~ +x (yaw pi/2)
    assert abs(math.sin(w.state.heading[i]) - 1.0) < 0.2
