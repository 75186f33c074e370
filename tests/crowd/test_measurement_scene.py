"""``[[measurement]]`` tables and ``[output] trajectories`` of a scene: parsing and one-line errors (crowd.measurement)."""
import pytest
from crowd_testutil import run_cli, tiny_scene

from crowd.errors import SceneError
from crowd.measurement import polygon_area, segments_intersect, simple_polygon_problem
from crowd.scene import load_scene

SQUARE = "polygon = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]"


def _scene(write_scene, measurement: str, output: str = ""):
    return write_scene(tiny_scene(append=measurement + ("\n[output]\n" + output if output else "")))


def test_measurements_parse(write_scene):
    p = _scene(write_scene, f'[[measurement]]\nname = "area"\n{SQUARE}\n'
                            '[[measurement]]\nname = "door"\nline = [[0.0, -0.5], [0.0, 0.5]]\n'
                            '[[measurement]]\nname = "both"\npolygon = [[0, 0], [2, 0], [2, 2], [0, 0]]\n'
                            'line = [[1e6, 0], [1e6, 1]]\n', "trajectories = true\n")
    s = load_scene(p)
    assert s.trajectories is True
    assert [m.name for m in s.measurements] == ["area", "door", "both"]
    assert s.measurements[0].polygon == ((-1, -1), (1, -1), (1, 1), (-1, 1)) and s.measurements[0].line is None
    assert s.measurements[1].line == ((0.0, -0.5), (0.0, 0.5)) and s.measurements[1].polygon is None
    assert len(s.measurements[2].polygon) == 3  # the repeated closing point is dropped
    assert load_scene(write_scene(tiny_scene(), "plain.toml")).measurements == ()
    assert load_scene(write_scene(tiny_scene(), "plain2.toml")).trajectories is False


@pytest.mark.parametrize("table, key, words", [
    ('polygon = [[0, 0], [1, 0]]', "measurement[0].polygon", "at least 3"),
    ('polygon = [[0, 0], [1, 1], [2, 2]]', "measurement[0].polygon", "non-zero area"),
    ('polygon = [[0, 0], [2, 2], [2, 0], [0, 2]]', "measurement[0].polygon", "simple polygon"),  # bow tie
    ('polygon = [[0, 0], [2, 0], [2, 2], [2, 2], [0, 2]]', "measurement[0].polygon", "coincide"),
    ('polygon = [[0, 0], [2, 0], [1, 0], [1, 1]]', "measurement[0].polygon", "simple polygon"),  # folds back
    ('polygon = [[0, 0], [1, "a"], [2, 2]]', "measurement[0].polygon[1]", "finite numbers"),
    ('polygon = [[0, 0], [1, nan], [2, 2]]', "measurement[0].polygon[1]", "finite numbers"),
    ('polygon = "square"', "measurement[0].polygon", "list"),
    ('line = [[0, 0], [0, 0]]', "measurement[0].line", "two distinct points"),
    ('line = [[0, 0], [0, 1], [1, 1]]', "measurement[0].line", "two [x, z] points"),
    ('line = [[0, 0]]', "measurement[0].line", "two [x, z] points"),
    ('', "measurement[0]", "`polygon`"),
    ('radius = 2.0\nline = [[0, 0], [0, 1]]', "measurement[0].radius", "unknown key"),
])
def test_bad_measurements_are_one_line(write_scene, table, key, words):
    p = _scene(write_scene, f'[[measurement]]\nname = "m"\n{table}\n')
    with pytest.raises(SceneError) as e:
        load_scene(p)
    msg = str(e.value)
    assert "\n" not in msg and e.value.key == key and words in msg, msg


def test_duplicate_and_empty_names(write_scene):
    p = _scene(write_scene, f'[[measurement]]\nname = "a"\n{SQUARE}\n[[measurement]]\nname = "a"\n{SQUARE}\n')
    with pytest.raises(SceneError, match=r"measurement\[1\]\.name: duplicate measurement name 'a'"):
        load_scene(p)
    with pytest.raises(SceneError, match=r"measurement\[0\]\.name: expected a non-empty"):
        load_scene(_scene(write_scene, f'[[measurement]]\nname = " "\n{SQUARE}\n'))
    with pytest.raises(SceneError, match=r"measurement\[0\]\.name: required"):
        load_scene(_scene(write_scene, f'[[measurement]]\n{SQUARE}\n'))
    with pytest.raises(SceneError, match=r"measurement: expected an array of tables"):
        load_scene(write_scene(tiny_scene().replace('name = "tiny"', 'name = "tiny"\nmeasurement = 3')))


def test_bad_trajectories_key(write_scene):
    with pytest.raises(SceneError, match=r"output\.trajectories: expected true or false"):
        load_scene(_scene(write_scene, "", 'trajectories = "yes"\n'))


def test_cli_exit_2_without_traceback(write_scene, tmp_path):
    p = _scene(write_scene, '[[measurement]]\nname = "m"\nline = [[1, 1], [1, 1]]\n')
    r = run_cli("run", p, "--out", tmp_path / "out", "--quiet")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.count("\n") == 1 and "measurement[0].line: expected two distinct points" in r.stderr
    assert not (tmp_path / "out").exists()


def test_polygon_helpers():
    sq = [(0, 0), (1, 0), (1, 1), (0, 1)]
    assert polygon_area(sq) == 1.0 and polygon_area(sq[::-1]) == -1.0
    far = [(x + 1e7, z - 1e7) for x, z in sq]  # far from the origin: relative to the first point, exact
    assert polygon_area(far) == 1.0 and simple_polygon_problem(far) is None
    assert simple_polygon_problem([(0, 0), (2, 0), (2, 2), (1, -1)]) is not None  # crossing edges
    assert simple_polygon_problem([(0, 0), (2, 0), (2, 2), (1, 0)]) is not None  # corner touching an edge
    assert simple_polygon_problem([(0, 0), (1, 0), (2, 0), (2, 2)]) is None  # a straight corner is fine
    assert segments_intersect((0, 0), (2, 0), (1, 0), (3, 0))  # collinear overlap
    assert not segments_intersect((0, 0), (1, 0), (2, 0), (3, 0))
