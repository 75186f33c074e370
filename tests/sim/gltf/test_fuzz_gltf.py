"""Fuzzing the glTF importer (sim.gltf.load.load_gltf) with hypothesis.

Every input derives from one valid skinned, animated file: the JSON is mutated
(wrong types, deleted keys, indices out of range, absurd counts, cyclic node
and joint hierarchies, unknown required extensions) and the GLB bytes are
truncated or corrupted. Each load must either give a character whose arrays
are finite and consistent, or raise ``AssetError`` with one sentence naming
the file; never another exception, never a hang. A sample goes through
``python -m crowd info`` in a subprocess: exit code 2 and one line on stderr.
"""
from __future__ import annotations

import copy
import json
import os
import struct
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from sim.errors import AssetError
from sim.gltf.load import load_gltf

REPO = Path(__file__).resolve().parents[3]
#: generated inputs per strategy in CI: two strategies per loader, >= 2,000 inputs per loader
FUZZ_EXAMPLES_CI = 1100
FUZZ_EXAMPLES = int(os.environ.get("CROWD_FUZZ_EXAMPLES", str(FUZZ_EXAMPLES_CI)))
FUZZ_SETTINGS = settings(max_examples=FUZZ_EXAMPLES, deadline=5000, derandomize=True, database=None,
                         suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

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


def _base() -> tuple[dict, bytes]:
    """A valid glTF: 2-joint skin over a quad, LINEAR rotation + STEP translation clip."""
    blob = bytearray()
    g = {"asset": {"version": "2.0"}, "buffers": [], "bufferViews": [], "accessors": []}

    def acc(arr, typ, ct, **extra):
        nonlocal blob
        while len(blob) % 4:
            blob.append(0)
        raw = np.ascontiguousarray(arr).tobytes()
        g["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(raw)})
        blob += raw
        nc = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[typ]
        g["accessors"].append({"bufferView": len(g["bufferViews"]) - 1, "componentType": ct,
                               "count": int(np.asarray(arr).size // nc), "type": typ, **extra})
        return len(g["accessors"]) - 1

    p = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    idx = np.array([0, 1, 2, 0, 2, 3], np.uint16)
    jn = np.array([[0, 1, 0, 0]] * 4, np.uint8)
    w = np.array([[1, 0, 0, 0], [0.5, 0.5, 0, 0], [0, 1, 0, 0], [0.25, 0.75, 0, 0]], np.float32)
    ib = np.tile(np.eye(4, dtype=np.float32), (2, 1, 1))
    ib[1, 3, 1] = -1.0  # column-major: translation -1 in y
    t = np.array([0.0, 0.5, 1.0], np.float32)
    q = np.array([[0, 0, 0, 1], [0, 0, 1, 0], [0, 0, 0, 1]], np.float32)  # 180 degrees about z in the middle
    tr = np.array([[0, 1, 0], [0, 1.2, 0], [0, 1, 0]], np.float32)
    prim = {"attributes": {"POSITION": acc(p, "VEC3", 5126, min=[0, 0, 0], max=[1, 1, 0]),
                           "JOINTS_0": acc(jn, "VEC4", 5121), "WEIGHTS_0": acc(w, "VEC4", 5126)},
            "indices": acc(idx, "SCALAR", 5123), "material": 0}
    g.update({
        "scene": 0, "scenes": [{"nodes": [0, 2]}],
        "nodes": [{"name": "root", "children": [1]}, {"name": "tip", "translation": [0, 1, 0]},
                  {"mesh": 0, "skin": 0, "name": "body"}],
        "meshes": [{"primitives": [prim]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.2, 0.2, 1.0]}}],
        "skins": [{"joints": [0, 1], "inverseBindMatrices": acc(ib, "MAT4", 5126)}],
        "animations": [{"name": "swing", "samplers": [
            {"input": acc(t, "SCALAR", 5126, min=[0.0], max=[1.0]), "output": acc(q, "VEC4", 5126)},
            {"input": 5, "output": acc(tr, "VEC3", 5126), "interpolation": "STEP"}],
            "channels": [{"sampler": 0, "target": {"node": 1, "path": "rotation"}},
                         {"sampler": 1, "target": {"node": 0, "path": "translation"}}]}],
    })
    g["buffers"].append({"byteLength": len(blob)})
    return g, bytes(blob)


BASE_JSON, BASE_BLOB = _base()


def glb_bytes(gltf: dict, blob: bytes) -> bytes:
    js = json.dumps(gltf, allow_nan=True).encode()
    js += b" " * (-len(js) % 4)
    blob = blob + b"\0" * (-len(blob) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(blob), 0x004E4942) + blob
    return struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body


def _paths(node, prefix=()):
    """Every (path) into a JSON tree, containers included."""
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, prefix + (i,))


ALL_PATHS = [p for p in _paths(BASE_JSON) if p]

wild = st.one_of(
    st.none(), st.booleans(), st.integers(-3, 12), st.sampled_from([-1, 2 ** 31, 2 ** 32 + 1, 2 ** 62, 10 ** 30]),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=6),
    st.lists(st.integers(-2, 10), max_size=5), st.dictionaries(st.text(max_size=4), st.integers(-2, 5), max_size=2),
    st.sampled_from(["SCALAR", "VEC3", "VEC4", "MAT4", "LINEAR", "STEP", "CUBICSPLINE", "rotation", "weights",
                     "translation", "scale", "data:,", "data:application/octet-stream;base64,@@", "missing.bin"]),
)

# structural mutations that stress specific checks
SPECIAL = [
    lambda g: g["nodes"][1].setdefault("children", []).append(0),             # cycle root <-> tip
    lambda g: g["nodes"][2].setdefault("children", []).append(2),             # self child
    lambda g: g["nodes"][1].update(children=[2]) or g["nodes"][2].update(children=[0]),  # 3-cycle
    lambda g: g["skins"][0].update(joints=[0, 1, 1, 0, 9]),
    lambda g: g.update(extensionsRequired=["EXT_unknown_thing"], extensionsUsed=["EXT_unknown_thing"]),
    lambda g: g.update(extensionsRequired=["KHR_draco_mesh_compression"]),
    lambda g: g["accessors"][0].update(count=2 ** 40),
    lambda g: g["accessors"][0].update(count=1 << 27),
    lambda g: g["accessors"][3].update(count=10 ** 6),
    lambda g: g["accessors"][3].update(byteOffset=2 ** 33),
    lambda g: g["bufferViews"][0].update(byteLength=2 ** 40),
    lambda g: g["bufferViews"][0].update(byteStride=1),
    lambda g: g["meshes"][0]["primitives"][0].update(mode=7),
    lambda g: g["meshes"][0]["primitives"][0].update(indices=99),
    lambda g: g["animations"][0]["channels"][0].update(sampler=42),
    lambda g: g["animations"][0]["channels"][0]["target"].update(node=-5),
    lambda g: g["animations"][0]["samplers"][0].update(input=1),            # joints as key times
    lambda g: g.update(scene=3),
    lambda g: g.pop("buffers"),
    lambda g: g["skins"][0].update(joints=[]),
    lambda g: g["nodes"][0].update(matrix=[1e308] * 16),
    lambda g: g["nodes"][1].update(rotation=[0, 0, 0, 0]),
    lambda g: g["nodes"][1].update(scale=[0, 0, 0]),
]


def _set(tree, path, value):
    node = tree
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value


def _delete(tree, path):
    node = tree
    for k in path[:-1]:
        node = node[k]
    del node[path[-1]]


@st.composite
def mutated_json(draw):
    g = copy.deepcopy(BASE_JSON)
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["set", "set", "delete", "special"]))
        try:
            if kind == "special":
                draw(st.sampled_from(SPECIAL))(g)
            else:
                path = draw(st.sampled_from(ALL_PATHS))
                if kind == "set":
                    _set(g, path, draw(wild))
                else:
                    _delete(g, path)
        except (KeyError, IndexError, TypeError, AttributeError):
            pass  # the path no longer exists after an earlier mutation
    return g


def check_outcome(path: Path):
    """Load ``path``: a consistent character or one-sentence AssetError; anything else fails."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            ch = load_gltf(path)
        except AssetError as e:
            msg = str(e)
            assert msg and "\n" not in msg, msg
            assert path.name in msg, msg
            return None
    if ch.kind == "skinned":
        m = ch.mesh
        assert np.isfinite(m.positions).all() and np.isfinite(m.normals).all()
        assert np.isfinite(m.weights).all()
        np.testing.assert_allclose(m.weights.sum(1), 1.0, atol=1e-5)
        assert m.indices.size == 0 or int(m.indices.max()) < m.n_vertices
        assert m.joints.size == 0 or int(m.joints.max()) < ch.skeleton.n_joints
        for c in ch.clips.values():
            assert np.isfinite(c.duration) and c.duration > 0
    return ch


@FUZZ_SETTINGS
@given(g=mutated_json())
def test_fuzz_json_mutations(tmp_path_factory, g):
    FUZZ_RUNS["test_fuzz_json_mutations"] = FUZZ_RUNS.get("test_fuzz_json_mutations", 0) + 1
    d = tmp_path_factory.mktemp("fz", numbered=True)
    p = d / "fuzz.glb"
    p.write_bytes(glb_bytes(g, BASE_BLOB))
    check_outcome(p)


BASE_GLB = glb_bytes(BASE_JSON, BASE_BLOB)


@st.composite
def corrupted_glb(draw):
    data = bytearray(BASE_GLB)
    kind = draw(st.sampled_from(["truncate", "flip", "both", "header"]))
    if kind in ("flip", "both"):
        for _ in range(draw(st.integers(1, 8))):
            i = draw(st.integers(0, len(data) - 1))
            data[i] = draw(st.integers(0, 255))
    if kind == "header":
        i = draw(st.integers(0, 27))
        data[i] = draw(st.integers(0, 255))
    if kind in ("truncate", "both"):
        data = data[: draw(st.integers(0, len(data) - 1))]
    return bytes(data)


@FUZZ_SETTINGS
@given(data=corrupted_glb())
def test_fuzz_truncated_and_corrupted_bytes(tmp_path_factory, data):
    FUZZ_RUNS["test_fuzz_truncated_and_corrupted_bytes"] = FUZZ_RUNS.get("test_fuzz_truncated_and_corrupted_bytes", 0) + 1
    p = tmp_path_factory.mktemp("fb", numbered=True) / "bytes.glb"
    p.write_bytes(data)
    check_outcome(p)


def test_base_file_is_valid(tmp_path):
    p = tmp_path / "base.glb"
    p.write_bytes(BASE_GLB)
    ch = check_outcome(p)
    assert ch is not None and ch.kind == "skinned" and list(ch.clips) == ["swing"]


@pytest.mark.parametrize("i", range(len(SPECIAL)))
def test_each_special_mutation(tmp_path, i):
    g = copy.deepcopy(BASE_JSON)
    SPECIAL[i](g)
    p = tmp_path / "special.glb"
    p.write_bytes(glb_bytes(g, BASE_BLOB))
    check_outcome(p)


_CLI_INFO_CHILD = """
import contextlib, io, json, sys
from crowd.cli import main
out = []
for path in sys.argv[1:]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(["info", path])
        except SystemExit as e:
            code = e.code
    out.append([path, code, err.getvalue()])
print(json.dumps(out))
"""


def test_cli_info_exit_2_on_a_sample(tmp_path):
    """A sample of bad files through ``crowd info`` (its ``main``, in one child
    process for all files): exit 2, one line naming the file, no traceback."""
    import json

    cases = []
    for i in (0, 2, 3, 4, 6, 10, 13, 18):
        g = copy.deepcopy(BASE_JSON)
        SPECIAL[i](g)
        cases.append(glb_bytes(g, BASE_BLOB))
    cases += [BASE_GLB[:11], BASE_GLB[:40], BASE_GLB[: len(BASE_GLB) // 2], b"", b"glTF" + b"\xff" * 30]
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    bad = []
    for k, data in enumerate(cases):
        p = tmp_path / f"case{k}.glb"
        p.write_bytes(data)
        try:
            load_gltf(p)
            continue  # still loadable (a mutation the importer tolerates)
        except AssetError:
            bad.append(str(p))
    assert len(bad) >= 8
    r = subprocess.run([sys.executable, "-c", _CLI_INFO_CHILD, *bad], capture_output=True, text=True,
                       cwd=REPO, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    results = json.loads(r.stdout.strip().splitlines()[-1])
    assert [p for p, _, _ in results] == bad
    for path, code, stderr in results:
        err = [ln for ln in stderr.splitlines() if "Warning" not in ln and not ln.startswith("  ")]
        assert code == 2, (path, stderr)
        assert "Traceback" not in stderr and len(err) == 1, (path, stderr)
        assert Path(path).name in err[0]
