"""The shipped replays (issue 46, item 3): scenes/replay_bottleneck.toml and scenes/replay_jupedsim.toml replay their
recordings on the recorded rows, every person in and out at their own frames, with walls read from a floor plan, and
PedPy's flow at the scene's line from the replay equals PedPy's on the file (within 1 %). The recordings live in
../shared/data/pedestrian beside the repository: without them these tests skip (the scenes are then refused with one
line, tests/crowd/test_crowd_scene_errors.py). The obstacles' ``walls_file`` is tested on a file of its own."""
from pathlib import Path

import numpy as np
import pytest
from crowd_testutil import REPO, run_cli, tiny_scene

from crowd.scene import load_scene, missing_data

SCENES = ["replay_bottleneck", "replay_jupedsim"]


@pytest.mark.parametrize("name", SCENES)
def test_shipped_replay_sits_on_the_recording_and_measures_its_flow(tmp_path, name):
    path = REPO / "scenes" / f"{name}.toml"
    if missing_data(path):
        pytest.skip(f"no data at {missing_data(path)[0]}")
    pedpy = pytest.importorskip("pedpy")
    from crowd.engine import Engine
    from crowd.report.pedestrian import analyse
    from crowd.trajectories import TrajectoryWriter

    scene = load_scene(path)
    eng = Engine(scene.with_overrides(size=(64, 36)), quiet=True)
    w = eng.world
    rec = w.resources["replay"].tracks[0].recording
    obstacles = w.resources["obstacles"]
    assert obstacles.pbound.shape[0] >= 2  # the floor plan's walls
    assert abs(scene.dt * rec.frame_rate - 1.0) < 1e-9 and scene.frames == int(rec.last_frame - rec.first_frame) + 1
    k = np.repeat(np.arange(rec.persons), np.diff(rec.start))
    traj = tmp_path / "trajectories.txt"
    n0 = w.state.n
    worst = 0.0
    with TrajectoryWriter(traj, scene.name, w.state.n, scene.dt) as out:
        for frame in range(scene.frames):
            eng.step()
            f = rec.first_frame + frame
            r = w.resources["replay"]
            assert w.state.n == int(rec.alive(f).sum()), frame
            rows = np.flatnonzero(rec.frames == f)
            want = dict(zip(k[rows].tolist(), rec.xy[rows]))
            got = w.state.position[:, [0, 2]]
            have = np.array([p in want for p in r.person.tolist()])
            if have.any():
                exp = np.array([want[p] for p in r.person[have].tolist()])
                worst = max(worst, float(np.abs(got[have] - exp).max()))
            out.write(frame, w.state.position, w.state.ids)
    assert worst < 1e-3
    r = w.resources["replay"]
    assert n0 + r.total_entered == rec.persons  # everyone came ...
    assert r.total_left == rec.persons - int(rec.alive(rec.last_frame).sum())  # ... and left after their last frame
    line = analyse(traj, scene.measurements, voronoi=False)[0]["line"]
    # PedPy on the file itself, the same line
    data = pedpy.load_trajectory(trajectory_file=Path(rec.source)) if rec.format == "txt" else \
        pedpy.load_trajectory_from_jupedsim_sqlite(trajectory_file=Path(rec.source))
    _, crossing = pedpy.compute_n_t(traj_data=data, measurement_line=pedpy.MeasurementLine(scene.measurements[0].line))
    fr = np.sort(crossing["frame"].to_numpy(np.float64))
    direct = (len(fr) - 1) / ((fr[-1] - fr[0]) / data.frame_rate)
    assert len(fr) >= 10 and line["crossings"] == len(fr)
    assert line["mean_flow"] == pytest.approx(direct, rel=0.01)


WKT = "POLYGON ((-4 -3, 4 -3, 4 3, -4 3, -4 -3), (-1 -1, 1 -1, 1 1, -1 1, -1 -1))"


def test_walls_file_puts_walls_round_the_outline_and_the_holes(tmp_path, write_scene):
    (tmp_path / "room.wkt").write_text(WKT)
    scene = load_scene(write_scene(tiny_scene(effects='["animation", { name = "obstacles", walls_file = "room.wkt", '
                                                      'wall_thickness = 0.2, wall_height = 2.0 }]')))
    ob = next(e for e in scene.effects if e.name == "obstacles")
    walls = ob.params["polygons"]
    assert len(walls) >= 2 and all(p["height"] == 2.0 and p["visible"] for p in walls)
    import shapely

    solid = shapely.union_all([shapely.Polygon(p["points"]) for p in walls])
    assert solid.contains(shapely.Point(0.0, 0.0)) or solid.intersects(shapely.Point(0.0, 0.0))  # the pillar
    assert solid.distance(shapely.Point(4.1, 0.0)) < 1e-9  # the outer wall, outside the room
    assert not solid.contains(shapely.Point(2.5, 0.0))  # the floor between them is free
    assert ob.params["walls_file"] == str((tmp_path / "room.wkt").resolve())


@pytest.mark.parametrize("line, key, words", [
    ('walls_file = "nope.wkt"', "walls_file", ["not found", "nope.wkt"]),
    ('walls_layer = "A"', "walls_layer", ["only with `walls_file`"]),
    ('walls_file = "open.wkt"', "walls_file", ["open.wkt"]),
])
def test_bad_walls_file_is_one_line(tmp_path, write_scene, line, key, words):
    (tmp_path / "open.wkt").write_text("LINESTRING (0 0, 1 1)")
    scene = write_scene(tiny_scene(effects='["animation", { name = "obstacles", ' + line + ' }]'))
    r = run_cli("validate", scene)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert f"{scene}: effects[1].{key}" in r.stderr, r.stderr
    for w in words:
        assert w in r.stderr, r.stderr


def test_a_recording_that_leaves_the_walkable_area_is_reported_and_replayed(tmp_path):
    """Person 1 walks from inside the room (x in [-4, 4], z in [-3, 3]) out through its wall to x = 6; person 2
    stays inside. With the room as routing's walkable area (and its walls drawn), validate says how many rows lie
    outside and how far, and the run replays them where they were recorded."""
    import sys

    sys.path.insert(0, str(REPO / "tests" / "sim"))
    from test_replay import scene_text, write_txt

    rows = [(1, f, -2.0 + 0.2 * f, 0.0) for f in range(41)] + [(2, f, 0.0, 1.0) for f in range(41)]
    file = write_txt(tmp_path / "out.txt", rows)
    (tmp_path / "room.wkt").write_text("POLYGON ((-4 -3, 4 -3, 4 3, -4 3, -4 -3))")
    text = scene_text(file, frames=41).replace(
        'effects = ["animation"]',
        'effects = ["animation", { name = "routing", walkable_file = "room.wkt" }]')
    scene = tmp_path / "scene.toml"
    scene.write_text(text)
    r = run_cli("validate", scene)
    assert r.returncode == 0, r.stderr
    notes = [ln for ln in r.stderr.splitlines() if "replayed as recorded" in ln]
    # x > 4 from frame 31 on: 10 rows outside, the last 2 m out (6 - 4)
    assert len(notes) == 1 and "placement[0]: 10 of the recording's 82 rows (1 of 2 people)" in notes[0], r.stderr
    assert "up to 2.00 m" in notes[0]
    from crowd.engine import Engine

    eng = Engine(load_scene(scene), quiet=True)
    for _ in range(41):
        eng.step()
    w = eng.world
    x = {int(w.resources["replay"].tracks[0].recording.ids[p]): w.state.position[a, 0]
         for a, p in enumerate(w.resources["replay"].person)}
    assert x[1] == pytest.approx(6.0, abs=1e-9) and x[2] == pytest.approx(0.0)  # drawn where recorded
