"""Replay of recorded crowds (issue 46, ``sim.replay``): recorded people appear at their first recorded frame, sit at
their recorded positions at the file's frames, leave after their last, face where they walk, and bad files give
one sentence naming the file."""
from pathlib import Path

import numpy as np
import pytest

from sim.params import ParamError
from sim.replay import from_columns, load

REPO = Path(__file__).resolve().parents[2]
PEDESTRIAN = REPO.parent / "shared" / "data" / "pedestrian"


def write_txt(path, rows, rate=25.0, unit="m", header=True):
    """A PeTrack/PedPy text file of rows (id, frame, x, y)."""
    lines = []
    if header:
        lines += [f"# framerate: {rate:g} fps", f"# id frame x/{unit} y/{unit} z/{unit}"]
    lines += [f"{int(i)}\t{int(f)}\t{x:.4f}\t{y:.4f}\t1.7" for i, f, x, y in rows]
    Path(path).write_text("\n".join(lines) + "\n")
    return Path(path)


def three_people():
    """Person 1: frames 0..40 walking +x at 1.25 m/s (25 fps); person 2: frames 10..30 standing near (0, 3) with
    1 cm of jitter; person 3: frames 20..60 walking -y at 0.75 m/s."""
    rng = np.random.default_rng(3)
    rows = [(1, f, -2.0 + 0.05 * f, 1.0) for f in range(0, 41)]
    rows += [(2, f, 0.0 + rng.uniform(-0.01, 0.01), 3.0 + rng.uniform(-0.01, 0.01)) for f in range(10, 31)]
    rows += [(3, f, 1.5, 4.0 - 0.03 * (f - 20)) for f in range(20, 61)]
    return rows


def scene_text(file, dt=0.04, frames=80, extra=""):
    return f"""name = "replay"
seed = 2
dt = {dt}
frames = {frames}
effects = ["animation"]

[[characters]]
name = "walker"
generator = "humanoid"
triangles = 600

[[placement]]
kind = "trajectories"
character = "walker"
clip = "walk"
file = "{file}"
{extra}
[camera]
position = [0.0, 8.0, -6.0]
target = [0.0, 0.0, 2.0]

[render]
size = [64, 48]
"""


def engine_of(tmp_path, file, **kw):
    from crowd.engine import Engine
    from crowd.scene import load_scene

    p = tmp_path / "scene.toml"
    p.write_text(scene_text(file, **kw))
    return Engine(load_scene(p), quiet=True)


def test_recording_interpolates_between_recorded_frames_and_clamps():
    rec = from_columns([7, 7, 7, 9], [0, 1, 3, 2], [[0, 0], [1, 0], [3, 2], [5, 5]], 10.0, "r.txt")
    assert list(rec.ids) == [7, 9] and list(rec.first) == [0, 2] and list(rec.last) == [3, 2]
    np.testing.assert_allclose(rec.at([0, 0, 0, 0], [0.5, 2.0, -4.0, 9.0]), [[0.5, 0], [2, 1], [0, 0], [3, 2]])
    np.testing.assert_allclose(rec.at([1], 2.0), [[5, 5]])
    assert list(rec.alive(2.0)) == [True, True] and list(rec.alive(2.5)) == [True, False]


def test_people_enter_and_leave_at_their_recorded_frames_and_sit_on_their_rows(tmp_path):
    rows = three_people()
    file = write_txt(tmp_path / "three.txt", rows)
    eng = engine_of(tmp_path, file)  # dt = 1 / 25: scene frame k shows recorded frame k
    w = eng.world
    assert "replay" in w.effects and w.state.n == 1  # person 1 only at the first frame
    by_person = {(i, f): (x, y) for i, f, x, y in rows}
    seen = {}
    for k in range(70):
        eng.step()
        expect = {i for i, f, _, _ in rows if f == k}
        r = w.resources["replay"]
        got = {int(r.tracks[0].recording.ids[p]) for p in r.person}
        assert got == expect, (k, got, expect)
        for a, p in enumerate(r.person):
            pid = int(r.tracks[0].recording.ids[p])
            x, y = by_person[(pid, k)]
            assert abs(w.state.position[a, 0] - x) < 1e-3 and abs(w.state.position[a, 2] - y) < 1e-3
            assert w.state.position[a, 1] == 0.0
            seen.setdefault(pid, set()).add(int(w.state.ids[a]))
    assert all(len(v) == 1 for v in seen.values())  # one stable id per person
    assert w.state.n == 0
    assert w.resources["replay"].total_entered == 2 and w.resources["replay"].total_left == 3


def test_positions_match_the_file_at_its_own_frames_when_the_scene_runs_faster(tmp_path):
    rows = three_people()
    file = write_txt(tmp_path / "three.txt", rows)
    eng = engine_of(tmp_path, file, dt=0.02)  # 50 fps: recorded frame f at scene frame 2 f
    w = eng.world
    rec = w.resources["replay"].tracks[0].recording
    for k in range(120):
        eng.step()
        if k % 2:
            continue
        f = k // 2
        r = w.resources["replay"]
        expect = sorted((i, x, y) for i, ff, x, y in rows if ff == f)
        got = sorted((int(rec.ids[p]), w.state.position[a, 0], w.state.position[a, 2]) for a, p in enumerate(r.person))
        assert [g[0] for g in got] == [e[0] for e in expect], k
        np.testing.assert_allclose(np.array(got)[:, 1:], np.array(expect)[:, 1:], atol=1e-3)


def test_heading_follows_the_walk_and_a_standing_person_does_not_spin(tmp_path):
    file = write_txt(tmp_path / "three.txt", three_people())
    eng = engine_of(tmp_path, file)
    w = eng.world
    rec = w.resources["replay"].tracks[0].recording
    headings = {}
    for k in range(45):
        eng.step()
        r = w.resources["replay"]
        for a, p in enumerate(r.person):
            headings.setdefault(int(rec.ids[p]), []).append((float(w.state.heading[a]), float(w.state.anim_rate[a])))
    h1 = np.array(headings[1])
    np.testing.assert_allclose(h1[5:, 0], np.pi / 2, atol=1e-6)  # walking +x: yaw 90 degrees (0 faces +z)
    assert (h1[5:, 1] > 0).all()  # the walk plays while walking
    h2 = np.array(headings[2])
    assert np.ptp(h2[:, 0]) == 0.0  # 1 cm of jitter turns nobody round
    assert (h2[:, 1] < 0.2).all()  # and barely walks
    h3 = np.array(headings[3])
    np.testing.assert_allclose(h3[3:, 0], np.pi, atol=1e-6)  # walking -y (sandbox -z)


def test_centimetres_land_in_metres(tmp_path):
    rows = [(1, f, 100.0 * f, 250.0) for f in range(5)]
    a = load(write_txt(tmp_path / "cm.txt", rows, unit="cm"))
    np.testing.assert_allclose(a.xy[:, 0], np.arange(5.0)) and np.testing.assert_allclose(a.xy[:, 1], 2.5)
    b = load(write_txt(tmp_path / "bare.txt", rows, header=False), unit="cm", frame_rate=25.0)
    np.testing.assert_allclose(b.xy, a.xy)
    assert b.frame_rate == 25.0


@pytest.mark.parametrize("case, words", [
    ("nan", ["NaN"]),
    ("duplicate", ["duplicate (id, frame)", "person 1, frame 2"]),
    ("truncated", ["missing values", "person 1, frame 7"]),
    ("empty", ["not a readable txt trajectory file"]),
    ("no-rate", ["not a readable txt trajectory file", "frame"]),
    ("unit-conflict", ["not a readable txt trajectory file"]),
    ("suffix", ["cannot tell the format", "'.dat'"]),
    ("jupedsim-not-sqlite", ["not a readable jupedsim trajectory file"]),
    ("vadere-no-rate", ["needs frame_rate"]),
])
def test_bad_recordings_are_one_sentence_naming_the_file(tmp_path, case, words):
    rows = [(1, f, 0.1 * f, 0.0) for f in range(5)]
    kw = {}
    if case == "nan":
        p = write_txt(tmp_path / "r.txt", rows)
        p.write_text(p.read_text().replace("0.2000", "nan"))
    elif case == "duplicate":
        p = write_txt(tmp_path / "r.txt", rows + [(1, 2, 5.0, 5.0)])
    elif case == "truncated":
        p = write_txt(tmp_path / "r.txt", rows)
        p.write_text(p.read_text() + "1\t7\t0.5")
    elif case == "empty":
        p = tmp_path / "r.txt"
        p.write_text("# framerate: 25 fps\n# id frame x/m y/m z/m\n")
    elif case == "no-rate":
        p = write_txt(tmp_path / "r.txt", rows, header=False)
        kw = {"unit": "m"}
    elif case == "unit-conflict":
        p = write_txt(tmp_path / "r.txt", rows, unit="cm")
        kw = {"unit": "m"}
    elif case == "suffix":
        p = tmp_path / "r.dat"
        p.write_text("1 0 0 0\n")
    elif case == "jupedsim-not-sqlite":
        p = tmp_path / "r.sqlite"
        p.write_text("not a database\n")
    else:
        p = tmp_path / "r.traj"
        p.write_text("pedestrianId simTime endTime-PID1 startX-PID1 startY-PID1 endX-PID1 endY-PID1\n")
    with pytest.raises(ParamError) as e:
        load(p, **kw)
    msg = e.value.message
    assert "\n" not in msg and (p.name in msg or case == "suffix"), msg
    for word in words:
        assert word in msg, msg


@pytest.mark.parametrize("name, file, kw", [
    ("bottleneck", "bottleneck/040_c_56_h-.txt", {}),
    ("jupedsim", "jupedsim/trajectories.sqlite", {}),
    ("vadere", "vadere/vadere_postvis.traj", {"frame_rate": 24.0}),
    ("pathfinder-csv", "pathfinder/pathfinder.csv", {}),
    ("pathfinder-json", "pathfinder/pathfinder.json", {}),
])
def test_real_recordings_replay_on_their_rows(tmp_path, name, file, kw):
    path = PEDESTRIAN / file
    if not path.is_file():
        pytest.skip(f"no shared pedestrian data at {path}")
    import pedpy  # noqa: F401  (the reference read)

    rec = load(path, **kw)
    from sim.replay.track import Track
    from sim.state import CrowdState  # noqa: F401

    # every recorded row, read back at its own frame, within 1 mm; the whole replay runs in the engine below
    k = np.repeat(np.arange(rec.persons), np.diff(rec.start))
    np.testing.assert_allclose(rec.at(k, rec.frames), rec.xy, atol=1e-9)
    extra = "".join(f"{a} = {v!r}\n" for a, v in kw.items())
    eng = engine_of(tmp_path, path, dt=1.0 / rec.frame_rate, extra=extra)
    w = eng.world
    track = w.resources["replay"].tracks[0]
    assert isinstance(track, Track)
    f0 = rec.first_frame
    for step in range(min(60, int(rec.last_frame - f0) + 1)):
        eng.step()
        f = f0 + step
        at_f = rec.frames == f
        r = w.resources["replay"]
        assert w.state.n == int(rec.alive(f).sum())
        expect = {int(p): rec.xy[(k == p) & at_f][0] for p in np.flatnonzero(rec.alive(f)) if ((k == p) & at_f).any()}
        for a, p in enumerate(r.person):
            if int(p) in expect:
                np.testing.assert_allclose(w.state.position[a, [0, 2]], expect[int(p)], atol=1e-3)


TWO_CHARACTERS = """
[[characters]]
name = "tall"
generator = "humanoid"
triangles = 600
scale = 1.5
"""


def many_people(path, n=400):
    """``n`` people, each recorded for 5 frames from frame i // 20, walking +x."""
    rows = [(i, i // 20 + k, 0.1 * k, 0.5 * i) for i in range(n) for k in range(5)]
    return write_txt(path, rows)


def test_people_draw_their_character_by_weight_and_keep_it(tmp_path):
    from crowd.engine import Engine
    from crowd.scene import load_scene

    text = scene_text(many_people(tmp_path / "many.txt"), extra="").replace(
        'character = "walker"\nclip = "walk"', 'character = { walker = 3, tall = 1 }\nclip = "walk"')
    text = text.replace("[[placement]]", TWO_CHARACTERS + "\n[[placement]]")
    (tmp_path / "scene.toml").write_text(text)
    eng = Engine(load_scene(tmp_path / "scene.toml"), quiet=True)
    w = eng.world
    seen = {}
    for _ in range(30):
        eng.step()
        st = w.state
        for i, c, s in zip(st.ids.tolist(), st.character.tolist(), st.scale.tolist()):
            assert seen.setdefault(i, (c, s)) == (c, s)  # a person keeps their character and scale
            assert s == pytest.approx(1.5 if c == 1 else 1.0)
    chars = np.array([c for c, _ in seen.values()])
    assert len(seen) > 300 and abs((chars == 0).mean() - 0.75) < 0.06
    assert set(np.unique(w.state.clip).tolist()) <= {0, 1}


def test_other_effects_do_not_move_recorded_people(tmp_path):
    rows = three_people()
    file = write_txt(tmp_path / "three.txt", rows)
    from crowd.engine import Engine
    from crowd.scene import load_scene

    text = scene_text(file).replace('effects = ["animation"]', 'effects = ["animation", "boids"]')
    (tmp_path / "scene.toml").write_text(text)
    eng = Engine(load_scene(tmp_path / "scene.toml"), quiet=True)
    w = eng.world
    rec = w.resources["replay"].tracks[0].recording
    at = {(i, f): (x, y) for i, f, x, y in rows}
    for k in range(40):
        eng.step()
        for a, p in enumerate(w.resources["replay"].person):
            x, y = at[(int(rec.ids[p]), k)]
            assert abs(w.state.position[a, 0] - x) < 1e-3 and abs(w.state.position[a, 2] - y) < 1e-3


@pytest.mark.parametrize("choice, key, words", [
    ("{ walker = 0 }", "placement[0].character.walker", ["weight > 0"]),
    ("{ runner = 1 }", "placement[0].character.runner", ["unknown character 'runner'"]),
    ("{}", "placement[0].character", ["at least one"]),
])
def test_bad_character_choice_is_one_line(tmp_path, choice, key, words):
    from crowd.errors import SceneError
    from crowd.scene import load_scene

    file = write_txt(tmp_path / "three.txt", three_people())
    (tmp_path / "scene.toml").write_text(scene_text(file).replace('character = "walker"\nclip',
                                                                  f'character = {choice}\nclip'))
    with pytest.raises(SceneError) as e:
        load_scene(tmp_path / "scene.toml")
    msg = str(e.value)
    assert key in msg and "\n" not in msg, msg
    for w in words:
        assert w in msg, msg


def test_a_recording_is_parsed_once_then_memory_mapped_from_the_cache(tmp_path, monkeypatch):
    import pedpy

    from sim.replay import cache

    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path / "cache"))
    file = write_txt(tmp_path / "three.txt", three_people())
    first = load(file)
    entries = sorted(p.name for p in cache.cache_dir().iterdir())
    assert len(entries) == 1 and not entries[0].startswith(".")  # one whole entry, no temporary left

    def no_parse(**kw):
        raise AssertionError("parsed again")

    monkeypatch.setattr(pedpy, "load_trajectory_from_txt", no_parse)
    again = load(file)
    assert isinstance(again.xy, np.memmap) and isinstance(again.keys, np.memmap)
    for name in ("ids", "start", "frames", "xy", "keys"):
        np.testing.assert_array_equal(getattr(again, name), getattr(first, name))
    np.testing.assert_array_equal(again.at([0, 1, 2], 20.5), first.at([0, 1, 2], 20.5))
    # another content is another entry (and is parsed); a broken entry is parsed and written again
    monkeypatch.undo()
    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path / "cache"))
    file.write_text(file.read_text().replace("\t1.7", "\t1.8", 1))
    load(file)
    assert len(list(cache.cache_dir().iterdir())) == 2
    (cache.cache_dir() / entries[0] / "xy.npy").unlink()
    file.write_text(file.read_text().replace("\t1.8", "\t1.7", 1))
    assert cache.load(entries[0]) is None
    np.testing.assert_array_equal(load(file).xy, first.xy)
    assert cache.load(entries[0]) is not None


def test_streamed_kinematics_are_the_searched_ones_frame_after_frame_and_back():
    """The replay streams the recording frame-major (sim.replay.frames: each person's segment from the frame
    before); forwards, backwards and from nothing it gives what a search from scratch (Recording.at) gives."""
    from sim.replay.track import SMOOTHING_S, Track

    rng = np.random.default_rng(4)
    ids, frames, xy = [], [], []
    for p in range(40):  # people with gaps in their frames and different spans
        f = np.sort(rng.choice(np.arange(200), size=rng.integers(2, 60), replace=False))
        ids += [p] * f.shape[0]
        frames += f.tolist()
        xy += rng.normal(size=(f.shape[0], 2)).tolist()
    rec = from_columns(ids, frames, xy, 25.0, "r.txt")
    track = Track(recording=rec, choices=np.array([[0, 0, 1.0, 1.0, 1.0]]))
    persons = np.arange(rec.persons)
    w = SMOOTHING_S * rec.frame_rate
    for f in list(np.arange(-5.0, 210.0, 0.37)) + [150.0, 3.2, 99.9]:  # forwards, then back
        got_xy, got_v = track.kinematics(persons, f)
        np.testing.assert_allclose(got_xy, rec.at(persons, f), rtol=0, atol=1e-12)
        lo, hi = rec.first, rec.last
        fa, fb = np.clip(f - w, lo, hi), np.clip(f + w, lo, hi)
        span = (fb - fa) / rec.frame_rate
        want_v = np.where(span[:, None] > 0, (rec.at(persons, fb) - rec.at(persons, fa))
                          / np.where(span > 0, span, 1.0)[:, None], 0.0)
        np.testing.assert_allclose(got_v, want_v, rtol=0, atol=1e-9)
