"""Fuzzing the scene-file loader (crowd.scene.load_scene) with hypothesis.

Documents start from a valid scene that uses every section (characters,
each placement kind, effects with parameters, terrain, camera keys, render,
lod, output) and get 1-3 mutations: wrong types, deleted keys, unknown keys,
absurd counts, huge numbers, NaN and infinities; the TOML text itself is also
truncated and corrupted. Each document must load into a Scene (whose memory
estimate is finite) or raise ``SceneError`` with one line naming the file;
never another exception. A sample goes through ``python -m crowd validate``:
exit code 2, one line on stderr, no traceback.
"""
from __future__ import annotations

import copy
import json
import math
import os

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from crowd_testutil import run_cli

from crowd.errors import SceneError
from crowd.memory import estimate_scene
from crowd.scene import load_scene

#: generated inputs per strategy in CI: two strategies per loader, >= 2,000 inputs per loader
FUZZ_EXAMPLES_CI = 1100
FUZZ_EXAMPLES = int(os.environ.get("CROWD_FUZZ_EXAMPLES", str(FUZZ_EXAMPLES_CI)))
FUZZ_SETTINGS = settings(max_examples=FUZZ_EXAMPLES, deadline=5000, derandomize=True, database=None,
                         suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])

#: examples each fuzz test really ran in this session (checked when the module ends)
FUZZ_RUNS: dict = {}


@pytest.fixture(scope="module", autouse=True)
def _fuzz_examples_really_ran():
    """Hypothesis may stop before ``max_examples`` (an exhausted search space,
    too many invalid inputs): fail the module if a fuzz test that ran executed
    fewer than FUZZ_EXAMPLES inputs."""
    yield
    short = {k: v for k, v in FUZZ_RUNS.items() if v < FUZZ_EXAMPLES}
    assert not short, f"fuzz tests ran fewer than {FUZZ_EXAMPLES} inputs: {short}"


BASE = {
    "name": "fuzz", "seed": 3, "dt": 0.05, "substeps": 2, "frames": 10,
    "effects": ["animation", {"name": "boids", "radius": 2.0}],
    "characters": [{"name": "walker", "generator": "humanoid", "triangles": 600, "seed": 1, "scale": 1.0, "fps": 30},
                   {"name": "dog", "generator": "quadruped", "triangles": 800}],
    "placement": [
        {"kind": "grid", "character": "walker", "rows": 2, "cols": 3, "spacing": [1.5, 1.5], "origin": [0.0, 0.0, 0.0],
         "heading": "random", "phase": "zero"},
        {"kind": "random", "character": "dog", "count": 5, "center": [10.0, 0.0, 0.0], "size": [5.0, 5.0],
         "min_distance": 0.5, "speed": 1.0},
        {"kind": "list", "character": "walker", "positions": [[0.0, 0.0, 5.0], [1.0, 0.0, 5.0]],
         "headings": [0.0, 90.0]},
        {"kind": "hierarchy", "character": "dog",
         "levels": [{"layout": "grid", "nx": 2, "nz": 2, "spacing": [1.0, 1.0]}]},
    ],
    "terrain": {"resolution": 9, "size": [40.0, 40.0]},
    "camera": {"fov": 50.0, "near": 0.1, "far": 500.0,
               "keys": [{"time": 0.0, "position": [0.0, 5.0, 20.0], "target": [0.0, 1.0, 0.0]},
                        {"time": 1.0, "position": [5.0, 5.0, 20.0], "target": [0.0, 1.0, 0.0]}]},
    "render": {"size": [64, 48], "background": [0.1, 0.1, 0.1], "png_every": 0},
    "lod": {"mode": "none"},
    "output": {"dir": "out/fuzz"},
}


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(v)


def to_toml(doc: dict) -> str:
    """Every top-level key as ``key = inline value`` (valid TOML for any JSON-like tree without None)."""
    return "".join(f"{json.dumps(str(k))} = {toml_value(v)}\n" for k, v in doc.items())


def _paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, prefix + (i,))


ALL_PATHS = [p for p in _paths(BASE) if p]

wild = st.one_of(
    st.booleans(), st.integers(-5, 20), st.sampled_from([-1, 0, 2 ** 31, 2 ** 63 - 1, -(2 ** 63), 10 ** 7, 10 ** 8]),
    st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([1e308, -1e308, 5e-324, 0.0, -0.0]),
    st.text(max_size=8), st.sampled_from(["walker", "dog", "grid", "random", "humanoid", "none", "boids", "../x.glb",
                                          "animation", "", "zero", "random"]),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=4),
    st.lists(st.integers(-3, 10 ** 9), max_size=4),
    st.dictionaries(st.sampled_from(["name", "kind", "layout", "x", "time"]), st.integers(-2, 5), max_size=2),
)


def _parent(tree, path):
    node = tree
    for k in path[:-1]:
        node = node[k]
    return node


@st.composite
def mutated_doc(draw):
    doc = copy.deepcopy(BASE)
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["set", "set", "set", "delete", "add"]))
        path = draw(st.sampled_from(ALL_PATHS))
        try:
            parent = _parent(doc, path)
            if kind == "set":
                parent[path[-1]] = draw(wild)
            elif kind == "delete":
                del parent[path[-1]]
            elif isinstance(parent, dict):
                parent[draw(st.text(min_size=1, max_size=6))] = draw(wild)
            else:
                parent.append(draw(wild))
        except (KeyError, IndexError, TypeError, AttributeError):
            pass  # the path no longer exists after an earlier mutation
    return doc


def check_scene(path):
    try:
        sc = load_scene(path)
    except SceneError as e:
        msg = str(e)
        assert msg and "\n" not in msg, msg
        assert str(path) in msg, msg
        return None
    e = estimate_scene(sc)
    assert e.agents >= 1 and math.isfinite(e.total) and e.total > 0
    assert math.isfinite(sc.dt) and 0 < sc.dt <= 1
    return sc


@FUZZ_SETTINGS
@given(doc=mutated_doc())
def test_fuzz_scene_documents(tmp_path, doc):
    FUZZ_RUNS["test_fuzz_scene_documents"] = FUZZ_RUNS.get("test_fuzz_scene_documents", 0) + 1
    p = tmp_path / "scene.toml"
    p.write_text(to_toml(doc))
    check_scene(p)


@FUZZ_SETTINGS
@given(cut=st.integers(0, 4000), flips=st.lists(st.tuples(st.integers(0, 4000), st.characters()), max_size=4))
def test_fuzz_scene_text(tmp_path, cut, flips):
    FUZZ_RUNS["test_fuzz_scene_text"] = FUZZ_RUNS.get("test_fuzz_scene_text", 0) + 1
    text = list(to_toml(BASE))
    for i, c in flips:
        text[i % len(text)] = c
    p = tmp_path / "scene.toml"
    p.write_text("".join(text)[: cut % (len(text) + 1)], encoding="utf-8", errors="surrogatepass")
    check_scene(p)


def test_base_scene_is_valid(tmp_path):
    p = tmp_path / "scene.toml"
    p.write_text(to_toml(BASE))
    sc = check_scene(p)
    assert sc is not None and len(sc.placements) == 4


CLI_CASES = [
    {"characters": [{"name": "walker", "generator": "humanoid", "triangles": 10 ** 9}]},
    {"dt": float("nan")},
    {"frames": 2 ** 63 - 1, "dt": float("inf")},
    {"render": {"size": [10 ** 9, -1]}},
    {"camera": {"near": float("nan")}},
    {"placement": [{"kind": "grid", "character": "walker", "rows": 10 ** 7, "cols": 10 ** 7}]},
    {"placement": [{"kind": "hierarchy", "character": "walker",
                    "levels": [{"layout": "grid", "nx": 10 ** 6, "nz": 10 ** 6, "spacing": [1.0, 1.0]}]}]},
    {"effects": [{"name": "boids", "radius": float("-inf")}]},
    {"terrain": {"resolution": 10 ** 9}},
    {"lod": {"mode": 7}},
]


@pytest.mark.parametrize("i", range(len(CLI_CASES)))
def test_cli_validate_exit_2(tmp_path, i):
    doc = copy.deepcopy(BASE)
    doc.update(CLI_CASES[i])
    p = tmp_path / "bad.toml"
    p.write_text(to_toml(doc))
    r = run_cli("validate", p, timeout=120)
    assert r.returncode == 2, r.stdout + r.stderr
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "bad.toml" in r.stderr


def test_cli_validate_and_run_scene_with_broken_gltf_exit_2(tmp_path):
    """A scene naming a truncated glTF file: one line naming the file, exit 2, no output directory."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "sim" / "gltf"))
    from test_fuzz_gltf import BASE_GLB

    (tmp_path / "broken.glb").write_bytes(BASE_GLB[: len(BASE_GLB) // 3])
    doc = copy.deepcopy(BASE)
    doc["characters"] = [{"name": "walker", "file": "broken.glb"}, {"name": "dog", "generator": "quadruped"}]
    doc["output"] = {"dir": str(tmp_path / "out")}
    p = tmp_path / "gl.toml"
    p.write_text(to_toml(doc))
    for cmd in (("validate", p), ("run", p, "--quiet")):
        r = run_cli(*cmd, timeout=120)
        assert r.returncode == 2, r.stdout + r.stderr
        assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert "broken.glb" in r.stderr
    assert not (tmp_path / "out").exists()
