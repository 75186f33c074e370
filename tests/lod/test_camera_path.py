"""lod.camera_path: time-knotted Catmull-Rom camera paths and their JSON files."""
import json

import numpy as np
import pytest

from lod.camera_path import CameraPath, CameraPathError, catmull_rom, load_path, save_path

KEYS = [
    (0.0, (0.0, 2.0, 10.0), (0.0, 1.0, 0.0)),
    (1.0, (10.0, 3.0, 0.0), (0.0, 1.0, 0.0)),
    (2.5, (0.0, 4.0, -10.0), (1.0, 1.0, 0.0)),
    (4.0, (-10.0, 2.0, 0.0), (0.0, 0.0, 0.0)),
]


def test_passes_through_every_key_exactly():
    path = CameraPath(KEYS)
    for t, p, g in KEYS:
        pos, tgt = path.pose_at(t)
        np.testing.assert_allclose(pos, p, atol=1e-12)
        np.testing.assert_allclose(tgt, g, atol=1e-12)


def test_clamped_before_first_and_after_last_key():
    path = CameraPath(KEYS)
    np.testing.assert_allclose(path.pose_at(-5.0)[0], KEYS[0][1])
    np.testing.assert_allclose(path.pose_at(100.0)[0], KEYS[-1][1])
    np.testing.assert_allclose(path.pose_at(100.0)[1], KEYS[-1][2])


def test_position_and_velocity_are_continuous_at_keys():
    path = CameraPath(KEYS)
    h = 1e-6
    for t, _, _ in KEYS[1:-1]:
        before, at, after = (path.pose_at(t + d)[0] for d in (-h, 0.0, h))
        # C0: no jump
        assert np.linalg.norm(after - before) < 1e-4
        # C1 in time: left and right difference quotients agree
        v_left, v_right = (at - before) / h, (after - at) / h
        np.testing.assert_allclose(v_left, v_right, atol=1e-3)


def test_dense_sampling_has_no_jumps():
    path = CameraPath(KEYS)
    t = np.linspace(0.0, 4.0, 4001)
    p, g = path.pose_at(t)
    assert p.shape == (4001, 3) and np.isfinite(p).all() and np.isfinite(g).all()
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    assert step.max() < 0.1  # ~30 m over 4 s sampled every ms


def test_single_key_is_a_fixed_camera():
    path = CameraPath([(2.0, (1.0, 2.0, 3.0), (0.0, 0.0, 0.0))])
    for t in (-1.0, 0.0, 2.0, 50.0):
        pos, tgt = path.pose_at(t)
        np.testing.assert_array_equal(pos, [1.0, 2.0, 3.0])
        np.testing.assert_array_equal(tgt, [0.0, 0.0, 0.0])


def test_two_keys_move_linearly_in_time():
    path = CameraPath([(0.0, (0.0, 0.0, 0.0), (0.0, 0.0, -1.0)), (2.0, (4.0, 0.0, 0.0), (4.0, 0.0, -1.0))])
    pos, _ = path.pose_at(np.array([0.5, 1.0, 1.5]))
    np.testing.assert_allclose(pos[:, 0], [1.0, 2.0, 3.0], atol=1e-12)


def test_uniform_spacing_matches_uniform_catmull_rom():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(5, 3))
    times = np.arange(5.0)
    u = 0.3
    p0, p1, p2, p3 = pts[0], pts[1], pts[2], pts[3]
    # classic uniform Catmull-Rom (tension 1/2) on segment 1..2
    ref = 0.5 * ((2 * p1) + (-p0 + p2) * u + (2 * p0 - 5 * p1 + 4 * p2 - p3) * u**2 + (-p0 + 3 * p1 - 3 * p2 + p3) * u**3)
    np.testing.assert_allclose(catmull_rom(times, pts, np.array([1.0 + u]))[0], ref, atol=1e-12)


def test_camera_at_looks_from_position_to_target():
    path = CameraPath(KEYS)
    cam = path.camera_at(1.7, fov_y=60.0, near=0.5, far=300.0)
    pos, tgt = path.pose_at(1.7)
    np.testing.assert_allclose(cam.position, pos)
    d = (tgt - pos) / np.linalg.norm(tgt - pos)
    np.testing.assert_allclose(cam.forward, d, atol=1e-12)
    assert (cam.fov_y, cam.near, cam.far) == (60.0, 0.5, 300.0)


def test_position_meeting_target_between_keys_stays_defined():
    # position and target swap places: midway they coincide
    path = CameraPath([(0.0, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0)), (1.0, (1.0, 0.0, 0.0), (0.0, 0.0, 0.0))])
    pos, tgt = path.pose_at(0.5)
    assert np.linalg.norm(tgt - pos) == pytest.approx(1.0)
    cam = path.camera_at(0.5)
    assert np.isfinite(cam.rotation).all()


@pytest.mark.parametrize("keys, match", [
    ([], "at least one key"),
    ([(0.0, (0, 0, 0), (0, 0, 1)), (0.0, (1, 0, 0), (0, 0, 1))], "strictly increasing"),
    ([(0.0, (0, 0, 0), (0, 0, 0))], "must differ"),
    ([(float("nan"), (0, 0, 0), (0, 0, 1))], "finite"),
    ([(0.0, (0, 0), (0, 0, 1))], "three finite numbers"),
    ([(0.0, (0, float("inf"), 0), (0, 0, 1))], "three finite numbers"),
    ([{"time": 0.0, "position": [0, 0, 0]}], "missing target"),
    ([{"time": 0.0, "position": [0, 0, 0], "target": [1, 0, 0], "roll": 3}], "unknown field 'roll'"),
])
def test_malformed_keys_are_rejected(keys, match):
    with pytest.raises(CameraPathError, match=match):
        CameraPath(keys)


def test_json_round_trip(tmp_path):
    path = CameraPath(KEYS)
    f = tmp_path / "paths" / "flyby.json"
    save_path(f, path)
    data = json.loads(f.read_text())
    assert isinstance(data, list) and set(data[0]) == {"time", "position", "target"}
    back = load_path(f)
    np.testing.assert_array_equal(back.times, path.times)
    np.testing.assert_array_equal(back.positions, path.positions)
    np.testing.assert_array_equal(back.targets, path.targets)
    assert [p.name for p in f.parent.iterdir()] == ["flyby.json"]  # no temp file left


def test_json_object_with_keys_is_accepted(tmp_path):
    f = tmp_path / "p.json"
    f.write_text(json.dumps({"keys": CameraPath(KEYS).keys()}))
    assert load_path(f).times.tolist() == [0.0, 1.0, 2.5, 4.0]


@pytest.mark.parametrize("text, match", [("{not json", "not valid JSON"), ('{"k": 1}', "object with `keys`"),
                                         ('"abc"', "list of keys")])
def test_bad_json_files(tmp_path, text, match):
    f = tmp_path / "p.json"
    f.write_text(text)
    with pytest.raises(CameraPathError, match=match):
        load_path(f)
