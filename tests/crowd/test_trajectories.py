"""``[output] trajectories``: the text PedPy reads, streamed by the engine, written with the run's outputs."""
import numpy as np
import pytest
from crowd_testutil import run_cli, tiny_scene

from crowd.trajectories import TRAJECTORY_FILE, TrajectoryWriter, format_frame, header, read_trajectories

WALK = tiny_scene(effects='[{ name = "goals", paths = [[[0.75, 500.0]]], loop = false, speed = 1.5 }]',
                  replace={"frames = 3": "frames = 8", "png_every = 1": "png_every = 0"},
                  append="\n[output]\ntrajectories = true\n")


def test_format_is_id_frame_then_pedpy_axes():
    pos = np.array([[1.0, 0.5, -2.0], [1e7 + 0.123456, 0.0, -1e7]])  # far from the origin: 4 decimals kept
    lines = format_frame(7, pos).splitlines()
    assert lines == ["0 7 1.0000 -2.0000 0.5000", "1 7 10000000.1235 -10000000.0000 0.0000"]
    assert format_frame(0, np.zeros((0, 3))) == ""
    h = header("a\nb", 3, 0.05, 2)
    assert h.count("\n") == 4 and "# framerate: 20.0\n" in h and "x/m y/m z/m" in h


def test_writer_streams_and_pedpy_reads_it(tmp_path):
    pedpy = pytest.importorskip("pedpy")  # the report extra; installed by make setup
    p = tmp_path / TRAJECTORY_FILE
    rng = np.random.default_rng(0)
    frames = [rng.uniform(-50, 50, (5, 3)) for _ in range(4)]
    with TrajectoryWriter(p, "t", 5, 0.04) as w:
        for f, pos in enumerate(frames):
            w.write(f, pos)
    assert w._f.closed and w.frames == 4
    rate, data = read_trajectories(p)
    assert rate == 25.0 and data.shape == (20, 5)
    traj = pedpy.load_trajectory_from_txt(trajectory_file=p)
    assert traj.frame_rate == 25.0
    df = traj.data.sort_values(["frame", "id"])
    want = np.concatenate(frames)
    np.testing.assert_allclose(df.x.to_numpy(), want[:, 0], atol=5e-5)  # PedPy x = sandbox x
    np.testing.assert_allclose(df.y.to_numpy(), want[:, 2], atol=5e-5)  # PedPy y = sandbox z (floor)
    assert df.id.tolist() == list(range(5)) * 4 and df.frame.tolist() == [f for f in range(4) for _ in range(5)]


def test_run_writes_every_agent_every_frame(write_scene, tmp_path):
    out = tmp_path / "out"
    r = run_cli("run", write_scene(WALK), "--out", out, "--quiet")
    assert r.returncode == 0, r.stderr
    rate, data = read_trajectories(out / TRAJECTORY_FILE)
    assert rate == pytest.approx(20.0) and data.shape == (4 * 8, 5)  # 2x2 grid, 8 frames
    assert np.array_equal(data[:, 1], np.repeat(np.arange(8), 4)) and np.array_equal(data[:, 0], np.tile(range(4), 8))
    z = data[:, 3].reshape(8, 4)
    np.testing.assert_allclose(np.diff(z, axis=0), 1.5 * 0.05, atol=2e-4)  # goals walk +z at 1.5 m/s
    import json

    assert json.loads((out / "summary.json").read_text())["trajectories"] == TRAJECTORY_FILE
    assert not list(tmp_path.glob(".out.*"))  # no temporary sibling left


def test_no_trajectories_unless_asked(write_scene, tmp_path):
    out = tmp_path / "out"
    r = run_cli("run", write_scene(WALK.replace("trajectories = true", "trajectories = false")), "--out", out, "-q")
    assert r.returncode == 0, r.stderr
    assert not (out / TRAJECTORY_FILE).exists()
