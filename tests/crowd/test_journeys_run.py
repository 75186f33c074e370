"""Runs whose agent count changes (sources, exits; crowd.population, sim.journeys): frames.csv, summary.json,
trajectories.txt and PedPy's N-t agree with what the simulation did; an agent that left is never drawn and an
entered one is, with its own stable id and colour; every LOD mode follows the changing count."""
import csv
import json

import numpy as np
import pytest

from crowd.engine import Engine
from crowd.scene import load_scene
from crowd.trajectories import read_trajectories

SCENE = """\
name = "flow"
seed = 1
dt = 0.1
frames = 130
effects = ["animation", "journeys", "avoidance"]

[[characters]]
name = "walker"
generator = "humanoid"
triangles = 600
seed = 7
radius = 0.25
variation = {{ hue = 0.45, saturation = 0.3, value = 0.3 }}

[[placement]]
kind = "grid"
character = "walker"
clip = "walk"
rows = 2
cols = 3
spacing = [1.0, 1.0]
origin = [-2.0, 0.0, -0.5]

[[stages]]
name = "door"
kind = "exit"
line = [[3.0, -1.5], [3.0, 1.5]]

[[journeys]]
name = "out"
placements = [0]
stages = ["door"]

[[sources]]
name = "west"
character = "walker"
journey = "out"
rate = {rate}
stop = {stop}
line = [[-4.0, -1.5], [-4.0, 1.5]]

[[measurement]]
name = "door"
line = [[3.0, -1.5], [3.0, 1.5]]

[camera]
position = [0.0, 14.0, 0.01]
target = [0.0, 0.0, 0.0]

[render]
size = [96, 64]
ground = false
background = [0.0, 0.0, 0.0]

[lod]
mode = "{mode}"
{lod}

[output]
trajectories = true
"""


def _scene(tmp_path, mode="none", lod="", rate=3.0, stop=4.0, name="flow.toml"):
    p = tmp_path / name
    p.write_text(SCENE.format(mode=mode, lod=lod, rate=rate, stop=stop))
    return load_scene(p)


def _frames(out):
    with open(out / "frames.csv") as f:
        return [{k: (float(v) if v not in ("",) else None) for k, v in r.items()} for r in csv.DictReader(f)]


@pytest.fixture(scope="module")
def flow_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("flow")
    sc = _scene(tmp)
    with Engine(sc, quiet=True) as e:
        res = e.run(out_dir=tmp / "out", png_every=0)
    return sc, res


def test_frames_and_summary_count_the_agents(flow_run):
    sc, res = flow_run
    rows = _frames(res.out_dir)
    agents = [int(r["agents"]) for r in rows]
    entered = [int(r["entered"]) for r in rows]
    left = [int(r["left"]) for r in rows]
    exited = [int(r["exited"]) for r in rows]
    prev = 6
    for a, e, lf in zip(agents, entered, left):
        assert a == prev + e - lf  # agents(f) = agents(f-1) + entered(f) - left(f)
        prev = a
    for r in rows:
        assert int(r["instances"]) + int(r["culled"]) == int(r["agents"])
    s = res.summary
    assert s["agents"] == 6 and s["agents_final"] == agents[-1]
    assert s["journeys"]["entered"] == sum(entered) == 13  # t = 0, 0.3, ..., 3.6 s at 3 agents/s until 4 s
    assert s["journeys"]["exited"] == sum(exited) == s["journeys"]["exits"]["door"] == 19
    assert sum(left) == 19 and agents[-1] == 0  # everyone walked out (and was removed two frames later)
    assert s["counts"]["agents"]["max"] == max(agents)


def test_trajectories_follow_stable_ids(flow_run):
    sc, res = flow_run
    rate, data = read_trajectories(res.out_dir / "trajectories.txt")
    assert rate == pytest.approx(10.0)
    rows = _frames(res.out_dir)
    per_frame = np.bincount(data[:, 1].astype(int), minlength=len(rows))
    assert per_frame.tolist() == [int(r["agents"]) for r in rows]
    ids = data[:, 0].astype(int)
    assert sorted(set(ids.tolist())) == list(range(6 + 13))  # entered agents got the next ids, none reused
    first = {}
    for i in np.unique(ids):
        f = np.sort(data[ids == i, 1].astype(int))
        assert np.array_equal(f, np.arange(f[0], f[-1] + 1))  # one run of frames: once gone, never back
        first[int(i)] = int(f[0])
    assert all(first[i] == 0 for i in range(6))
    order = [first[i] for i in range(6, 19)]
    assert order == sorted(order)  # ids in order of entry
    # every agent's last two rows are past the door (it walked on through it for one frame)
    for i in np.unique(ids):
        last = data[ids == i][np.argsort(data[ids == i, 1])][-2:]
        assert np.all(last[:, 2] > 3.0)


def test_pedpy_counts_the_exits(flow_run):
    pedpy = pytest.importorskip("pedpy")
    from pathlib import Path

    sc, res = flow_run
    traj = pedpy.load_trajectory_from_txt(trajectory_file=Path(res.out_dir / "trajectories.txt"))
    nt, crossing = pedpy.compute_n_t(traj_data=traj, measurement_line=pedpy.MeasurementLine([(3.0, -1.5), (3.0, 1.5)]))
    rows = _frames(res.out_dir)
    ours = np.repeat([int(r["frame"]) for r in rows], [int(r["exited"]) for r in rows])
    assert sorted(crossing["frame"].tolist()) == ours.tolist()  # the same agents, in the same frames
    assert int(nt["cumulative_pedestrians"].iloc[-1]) == res.summary["journeys"]["exits"]["door"]


def test_left_agents_are_not_drawn_and_entered_keep_their_colour(tmp_path):
    from lod.variation import variation_table

    sc = _scene(tmp_path)
    with Engine(sc, quiet=True) as e:
        e._open_renderer()
        vs = [dict(c.variation) if c.variation else None for c in sc.characters]
        words = {}
        seen_empty = lit = False
        for f in range(130):
            e.step()
            st = e.world.state
            cam = e.camera_at(e.world.time)
            dl = e.select(cam, sc.render.size)
            drawn = np.concatenate([np.asarray(b.instance_ids) for b in dl.batches] or [np.zeros(0, int)])
            assert np.array_equal(np.sort(drawn), np.arange(st.n))  # every agent alive, once; nobody else
            table = e.renderer.tint_table
            assert np.array_equal(table, variation_table(sc.seed, st.character, vs, ids=st.ids))
            for i, a in enumerate(st.ids.tolist()):
                assert words.setdefault(a, int(table[i])) == int(table[i])  # its colour, whatever its index
            e.renderer.draw(dl, sc.render.background)
            img = e.renderer.read_pixels()
            if st.n == 0:
                assert img[..., :3].max() == 0  # everyone left: nothing is drawn
                seen_empty = True
            else:
                lit |= img[..., :3].max() > 0
        assert seen_empty and lit
        assert len(set(words.values())) > 10  # words by id: the agents differ


@pytest.mark.parametrize("mode,lod", [("triangles", "keyframe_every = 3"), ("clusters", ""), ("points", ""),
                                      ("auto", "keyframe_every = 2")])
def test_lod_modes_follow_the_changing_count(tmp_path, mode, lod):
    sc = _scene(tmp_path, mode=mode, lod=lod, rate=5.0, stop=1.5)
    with Engine(sc, overrides={"frames": 40}, quiet=True) as e:
        res = e.run(out_dir=tmp_path / "out", png_every=0)
    rows = _frames(res.out_dir)
    assert any(int(r["left"]) for r in rows) and any(int(r["entered"]) for r in rows)
    for r in rows:
        assert int(r["instances"]) + int(r["culled"]) == int(r["agents"])
    data = json.loads((res.out_dir / "summary.json").read_text())
    assert data["journeys"]["entered"] == 8


def test_memory_guard_counts_the_agents_sources_add(tmp_path):
    from crowd.memory import estimate_scene

    quiet = estimate_scene(_scene(tmp_path, rate=3.0, stop=4.0, name="a.toml"))
    busy = estimate_scene(_scene(tmp_path, rate=300.0, stop=4.0, name="b.toml"))
    assert quiet.agents == 6 + 13 and busy.agents == 6 + 1201  # 13 / 1201 arrivals before 4 s (+1: the one at 4 s)
    assert busy.parts["state"] > quiet.parts["state"]
