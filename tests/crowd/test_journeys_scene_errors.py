"""Bad [[stages]] / [[journeys]] / [[sources]]: one line naming the file and the key, exit 2, nothing written
(crowd/scene_journeys.py; the unreachable-stage check of sim/journeys/reach.py before the run)."""
import pytest

from crowd_testutil import run_cli, tiny_scene

from crowd.errors import SceneError
from crowd.scene import load_scene

BASE = {"effects": '["animation", "journeys"]'}
STAGES = """
[[stages]]
name = "door"
kind = "exit"
line = [[5.0, -1.0], [5.0, 1.0]]

[[stages]]
name = "kiosk"
kind = "waypoint"
point = [2.0, 0.0]

[[journeys]]
name = "out"
placements = [0]
stages = ["kiosk", "door"]

[[sources]]
name = "west"
character = "walker"
journey = "out"
rate = 1.0
polygon = [[-6.0, -1.0], [-4.0, -1.0], [-4.0, 1.0], [-6.0, 1.0]]
"""
WALL = ', { name = "obstacles", boxes = [{ center = [-5.0, 0.0], size = [4.0, 4.0] }] }]'


def _text(replace=None, effects=BASE["effects"], stages=STAGES, append=""):
    s = stages
    for old, new in (replace or {}).items():
        assert old in s, old
        s = s.replace(old, new)
    return tiny_scene(effects=effects, append=s + append)


CLI_CASES = [
    ("source-outside-the-area", _text(effects='["animation", "journeys"' + WALL), "sources[0].polygon",
     ["outside the walkable area", "effects[2]"]),
    ("exit-zero-width", _text({"line = [[5.0, -1.0], [5.0, 1.0]]": "line = [[5.0, 1.0], [5.0, 1.0]]"}),
     "stages[0].line", ["zero width"]),
    ("unreachable-stage", tiny_scene(
        effects='["animation", "journeys", { name = "obstacles", agent_radius = 0.2, boxes = ['
                '{ center = [5.0, 2.0], size = [4.4, 0.4] }, { center = [5.0, -2.0], size = [4.4, 0.4] }, '
                '{ center = [3.0, 0.0], size = [0.4, 4.4] }, { center = [7.0, 0.0], size = [0.4, 4.4] }] }]',
        append=STAGES.replace("[2.0, 0.0]", "[5.0, 0.0]")), "journeys[0]",
     ["4 of 4 agents of journey 'out' cannot reach stage 'kiosk'", "agents 0, 1, 2, 3 of placement[0]"]),
    ("source-unknown-clip", _text({'rate = 1.0': 'rate = 1.0\nclip = "moonwalk"'}), "sources[0].clip",
     ["'moonwalk'", "accepted"]),
]


@pytest.mark.parametrize("text, key, words", [c[1:] for c in CLI_CASES], ids=[c[0] for c in CLI_CASES])
def test_bad_journeys_are_one_line_exit_2_nothing_written(tmp_path, write_scene, text, key, words):
    scene = write_scene(text)
    out = tmp_path / "out"
    r = run_cli("run", scene, "--out", out, "--quiet")
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert f"{scene}: {key}" in lines[0], lines[0]
    for w in words:
        assert w in lines[0], lines[0]
    assert "Traceback" not in r.stderr and r.stdout == ""
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]


CASES = [
    ("stages-without-effect", _text(effects='["animation"]'), "stages", ["needs the effect 'journeys'"]),
    ("effect-without-journeys", tiny_scene(effects=BASE["effects"]), "effects[1]", ["at least one [[journeys]]"]),
    ("with-goals", _text(effects='["animation", "journeys", "goals"]'), "effects[2]", ["'goals'", "both steer"]),
    ("unknown-stage", _text({'stages = ["kiosk", "door"]': 'stages = ["kiosk", "gate"]'}), "journeys[0].stages[1]",
     ["unknown stage 'gate'", "'kiosk'"]),
    ("exit-not-last", _text({'stages = ["kiosk", "door"]': 'stages = ["door", "kiosk"]'}), "journeys[0].stages[0]",
     ["only be the last"]),
    ("exit-and-waypoint-choice", _text({'stages = ["kiosk", "door"]': 'stages = [{kiosk = 1, door = 1}]'}),
     "journeys[0].stages[0]", ["all exits or none"]),
    ("negative-weight", _text({'stages = ["kiosk", "door"]': 'stages = [{kiosk = -1.0}, "door"]'}),
     "journeys[0].stages[0].kiosk", ["expected >= 0"]),
    ("duplicate-stage", _text({'name = "kiosk"': 'name = "door"'}), "stages[1].name", ["duplicate name 'door'"]),
    ("unknown-kind", _text({'kind = "waypoint"': 'kind = "portal"'}), "stages[1].kind", ["'waypoint'", "'queue'"]),
    ("waypoint-without-point", _text({"point = [2.0, 0.0]": ""}), "stages[1].point", ["needs `point"]),
    ("key-of-another-kind", _text({"point = [2.0, 0.0]": "point = [2.0, 0.0]\nspacing = 1.0"}), "stages[1].spacing",
     ["not a key of a waypoint"]),
    ("exit-polygon-self-intersecting", _text({"line = [[5.0, -1.0], [5.0, 1.0]]":
                                              "polygon = [[5.0, 0.0], [6.0, 1.0], [6.0, 0.0], [5.0, 1.0]]"}),
     "stages[0].polygon", ["simple polygon"]),
    ("exit-polygon-zero-area", _text({"line = [[5.0, -1.0], [5.0, 1.0]]":
                                      "polygon = [[5.0, 0.0], [6.0, 0.0], [7.0, 0.0]]"}),
     "stages[0].polygon", ["non-zero area"]),
    ("exit-line-and-polygon", _text({"line = [[5.0, -1.0], [5.0, 1.0]]":
                                     "line = [[5.0, -1.0], [5.0, 1.0]]\npolygon = [[5, 0], [6, 0], [6, 1]]"}),
     "stages[0]", ["exactly one of"]),
    ("wait-time-table", _text(append='\n[[stages]]\nname = "w"\nkind = "wait"\nslots = [[0.0, 0.0]]\n'
                              'time = { kind = "gamma", mean = 2.0 }\n'), "stages[2].time.kind", ["'uniform'"]),
    ("wait-uniform-max-below-min", _text(append='\n[[stages]]\nname = "w"\nkind = "wait"\nslots = [[0.0, 0.0]]\n'
                                         'time = { kind = "uniform", min = 3.0, max = 1.0 }\n'),
     "stages[2].time.max", [">= min"]),
    ("wait-area-too-small", _text(append='\n[[stages]]\nname = "w"\nkind = "wait"\nspacing = 5.0\n'
                                  'polygon = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]\n'),
     "stages[2].spacing", ["no slot"]),
    ("queue-without-line", _text(append='\n[[stages]]\nname = "q"\nkind = "queue"\n'), "stages[2]", ["needs `line`"]),
    ("queue-zero-length", _text(append='\n[[stages]]\nname = "q"\nkind = "queue"\nline = [[1.0, 1.0], [1.0, 1.0]]\n'),
     "stages[2].line", ["non-zero length"]),
    ("placement-out-of-range", _text({"placements = [0]": "placements = [3]"}), "journeys[0].placements[0]",
     ["no placement[3]"]),
    ("placement-twice", _text(append='\n[[journeys]]\nname = "again"\nplacements = [0]\nstages = ["door"]\n'),
     "journeys[1].placements", ["already follows journeys[0]"]),
    ("loop-with-exit", _text({"placements = [0]": "placements = [0]\nloop = true"}), "journeys[0].loop",
     ["cannot loop"]),
    ("source-unknown-journey", _text({'journey = "out"': 'journey = "home"'}), "sources[0].journey",
     ["unknown journey 'home'"]),
    ("source-unknown-character", _text({'character = "walker"\njourney': 'character = "runner"\njourney'}),
     "sources[0].character", ["unknown character 'runner'"]),
    ("source-zero-rate", _text({"rate = 1.0": "rate = 0.0"}), "sources[0].rate", ["expected >="]),
    ("source-two-areas", _text({"rate = 1.0": "rate = 1.0\nline = [[0.0, 0.0], [1.0, 0.0]]"}), "sources[0]",
     ["exactly one of"]),
    ("source-line-zero-length", _text({"polygon = [[-6.0, -1.0], [-4.0, -1.0], [-4.0, 1.0], [-6.0, 1.0]]":
                                       "line = [[0.0, 0.0], [0.0, 0.0]]"}), "sources[0].line", ["distinct"]),
    ("source-stop-before-start", _text({"rate = 1.0": "rate = 1.0\nstart = 5.0\nstop = 1.0"}), "sources[0].stop",
     [">= start"]),
    ("with-instancing", _text(effects='["animation", "journeys", "instancing"]'), "effects[2]", ["'instancing'"]),
    ("not-a-table-array", tiny_scene(effects=BASE["effects"], replace={'name = "tiny"': 'name = "tiny"\nsources = 3'},
                                     append=STAGES[:STAGES.index("[[sources]]")]), "sources", ["array of tables"]),
]


@pytest.mark.parametrize("text, key, words", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_journeys_name_file_and_key(tmp_path, write_scene, text, key, words):
    scene = write_scene(text)
    with pytest.raises(SceneError) as e:
        load_scene(scene)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{scene}: {key}: "), msg
    for w in words:
        assert w in msg, msg
