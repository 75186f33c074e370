"""Replayed recordings through the app (issue 46): a run's own trajectories.txt replays in place, the positions
drawn in every LOD mode are the recording's, ``crowd report`` measures the replay as PedPy measures the file and
names it, and a bad recording is one line, exit 2, nothing written."""
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from crowd_testutil import REPO, run_cli

from crowd.trajectories import read_trajectories

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "sim"))
from test_replay import engine_of, scene_text, three_people, write_txt  # noqa: E402

WALKERS = """\
name = "walkers"
seed = 4
dt = 0.05
frames = 40
effects = [{ name = "goals", paths = [[[6.0, 9.0]]], loop = false, speed = 1.2, arrive_radius = 0.01 }]

[[characters]]
name = "walker"
generator = "humanoid"
triangles = 600

[[placement]]
kind = "grid"
character = "walker"
rows = 2
cols = 3
spacing = [1.0, 1.5]
origin = [-1.0, 0.0, -2.0]

[camera]
position = [0.0, 6.0, -8.0]
target = [0.0, 0.0, 1.0]

[render]
size = [64, 48]

[output]
trajectories = true
"""


def test_a_runs_own_trajectories_replay_in_place(tmp_path):
    (tmp_path / "walkers.toml").write_text(WALKERS)
    r = run_cli("run", tmp_path / "walkers.toml", "--out", tmp_path / "a", "--quiet")
    assert r.returncode == 0, r.stderr
    first = tmp_path / "a" / "trajectories.txt"
    (tmp_path / "replay.toml").write_text(scene_text(first, dt=0.05, frames=40) + "\n[output]\ntrajectories = true\n")
    r = run_cli("run", tmp_path / "replay.toml", "--out", tmp_path / "b", "--quiet")
    assert r.returncode == 0, r.stderr
    rate_a, a = read_trajectories(first)
    rate_b, b = read_trajectories(tmp_path / "b" / "trajectories.txt")
    assert rate_a == rate_b == 20.0 and a.shape == b.shape == (6 * 40, 5)
    np.testing.assert_array_equal(a[:, :2], b[:, :2])  # the same ids in the same frames
    np.testing.assert_allclose(b[:, 2:4], a[:, 2:4], atol=1e-4)  # positions to the file's 4 decimals
    assert np.ptp(a[:, 3]) > 1.0  # they walked


BOTTLENECK = REPO.parent / "shared" / "data" / "pedestrian" / "bottleneck" / "040_c_56_h-.txt"


@pytest.mark.parametrize("data", ["synthetic", "bottleneck"])
@pytest.mark.parametrize("mode", ["none", "points", "clusters", "triangles", "auto"])
def test_positions_drawn_are_the_recordings_in_every_lod_mode(tmp_path, mode, data):
    """With ``feet = "recorded"`` the drawn positions are the recording's (planted feet: test_replay_feet)."""
    if data == "bottleneck":
        if not BOTTLENECK.is_file():
            pytest.skip(f"no shared pedestrian data at {BOTTLENECK}")
        from sim.replay import load

        r0 = load(BOTTLENECK)
        rows = [(int(r0.ids[p]), int(f), x, y) for p, (f, (x, y)) in
                zip(np.repeat(np.arange(r0.persons), np.diff(r0.start)), zip(r0.frames, r0.xy)) if f < 45]
        eng = engine_of(tmp_path, BOTTLENECK, extra='feet = "recorded"\n')
    else:
        rows = three_people()
        eng = engine_of(tmp_path, write_txt(tmp_path / "three.txt", rows), extra='feet = "recorded"\n')
    eng.set_lod_mode(mode)
    rec = eng.world.resources["replay"].tracks[0].recording
    at = {(i, f): (x, y) for i, f, x, y in rows}
    drawn = 0
    for k in range(45):
        eng.step()
        dl = eng.select(eng.camera_at(eng.world.time), eng.scene.render.size)
        person = eng.world.resources["replay"].person
        for b in dl.batches:
            if b.rep.startswith("world:"):
                continue
            t = b.instance_data[:, [3, 7, 11]].astype(np.float64) + np.asarray(dl.origin)
            for a, xyz in zip(np.asarray(b.instance_ids), t):
                x, y = at[(int(rec.ids[person[a]]), k)]
                assert abs(xyz[0] - x) < 1e-3 and abs(xyz[2] - y) < 1e-3 and abs(xyz[1]) < 1e-3
                drawn += 1
    assert drawn >= 60  # the three people were drawn, not culled away


SINGLE_FILE_LINE = """
[[measurement]]
name = "exit"
line = [[-1.0, 0.0], [1.0, 0.0]]
"""


def single_file(path):
    """Twelve people entering one after another 0.8 s apart (25 fps), walking 1.25 m/s along +y from y = -3 to
    y = 3, then leaving: each crosses y = 0 2.4 s after entering, one every 0.8 s (1.25 / s)."""
    rows = []
    for i in range(12):
        f0 = 20 * i
        rows += [(i + 1, f0 + k, 0.02 * i, -3.0 + 0.05 * k) for k in range(121)]
    return write_txt(path, rows)


def test_report_measures_the_replay_as_pedpy_measures_the_file_and_names_it(tmp_path):
    pedpy = pytest.importorskip("pedpy")
    file = single_file(tmp_path / "single.txt")
    (tmp_path / "replay.toml").write_text(scene_text(file, dt=0.04, frames=360) + SINGLE_FILE_LINE)
    r = run_cli("report", tmp_path / "replay.toml", "--cluster", "none", "--out", tmp_path / "report", "--quiet",
                timeout=600)
    assert r.returncode == 0, r.stderr
    data = json.loads((tmp_path / "report" / "report.json").read_text())
    ped = data["scenes"][0]["pedestrian"]
    line = ped["measurements"][0]["line"]
    # PedPy directly on the file, the same line
    traj = pedpy.load_trajectory(trajectory_file=file)
    nt, crossing = pedpy.compute_n_t(traj_data=traj, measurement_line=pedpy.MeasurementLine([(-1, 0), (1, 0)]))
    fr = np.sort(crossing["frame"].to_numpy(np.float64))
    direct = (len(fr) - 1) / ((fr[-1] - fr[0]) / traj.frame_rate)
    assert line["crossings"] == len(fr) == 12
    assert line["mean_flow"] == pytest.approx(direct, rel=0.01) and direct == pytest.approx(1.25, rel=1e-6)
    assert ped["sources"] == [{"file": "single.txt", "format": "txt", "persons": 12, "frame_rate": 25.0,
                               "seconds": pytest.approx(13.6)}]
    html = (tmp_path / "report" / "index.html").read_text()
    assert "Data: replayed from single.txt (txt, 12 people recorded over 13.6 s at 25 fps" in html


@pytest.mark.parametrize("text, words", [
    ("1\t0\t0.0\t0.0\t1.7\n1\t0\t0.5\t0.0\t1.7\n", ["duplicate (id, frame)"]),
    ("1\t0\tnan\t0.0\t1.7\n", ["NaN"]),
    ("1\t0\t0.0\n", ["not a readable txt trajectory file", "at least 5 columns"]),
])
def test_bad_recording_is_one_line_exit_2_nothing_written(tmp_path, text, words):
    (tmp_path / "bad.txt").write_text("# framerate: 25 fps\n# id frame x/m y/m z/m\n" + text)
    scene = tmp_path / "scene.toml"
    scene.write_text(scene_text(tmp_path / "bad.txt"))
    out = tmp_path / "out"
    r = run_cli("run", scene, "--out", out, "--quiet")
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert f"{scene}: placement[0].file: bad.txt: " in lines[0], lines[0]
    for w in words:
        assert w in lines[0], lines[0]
    assert not out.exists()
