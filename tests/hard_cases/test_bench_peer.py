"""scripts/bench_peer.py (issue 21): the scenario both engines draw, the generated characters, bad options."""
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))

import bench_peer  # noqa: E402
import peer_models  # noqa: E402


def test_scenario_grid_and_camera():
    sc = bench_peer.scenario(2.0, 10)  # 4 columns, 3 rows, spacing 3 m
    pos = np.asarray(sc["positions"])
    assert pos.shape == (10, 3) and sc["spacing"] == 3.0
    assert np.allclose(np.unique(np.round(pos[:, 0], 9)), [-4.5, -1.5, 1.5, 4.5])
    assert np.allclose(np.unique(np.round(pos[:, 2], 9)), [-3.0, 0.0, 3.0])
    w = 4 * 3.0
    assert np.allclose(sc["eye"], [0.0, 0.5 * w, 0.5 * 3 * 3.0 + 0.6 * w])  # above the near edge's middle
    assert sc["target"] == [0.0, 0.0, 0.0] and sc["fov"] == 50.0 and 0 < sc["near"] < sc["far"]


def test_generated_characters():
    from sim.procedural import humanoid

    ch = peer_models.four_influences(humanoid(1500, seed=1))
    w = np.asarray(ch.mesh.weights)
    j = np.asarray(ch.mesh.joints).astype(int)
    assert np.all((w > 0).sum(1) == 4) and np.allclose(w.sum(1), 1.0, atol=1e-6)
    assert all(len(set(r)) == 4 for r in j)  # four distinct joints
    ch = peer_models.one_influence(humanoid(1500, seed=1))
    assert np.all((np.asarray(ch.mesh.weights) > 0).sum(1) == 1)
    pieces = peer_models.split_primitives(ch.mesh.indices, np.asarray(ch.mesh.joints)[:, 0].astype(int), 59)
    assert len(pieces) >= 50
    got = sorted(map(tuple, np.concatenate(pieces).tolist()))
    assert got == sorted(map(tuple, np.asarray(ch.mesh.indices).reshape(-1, 3).tolist()))  # every triangle once


def _run(*args):
    return subprocess.run([sys.executable, str(ROOT / "scripts" / "bench_peer.py"), *args], capture_output=True,
                          text=True, cwd=ROOT)


def test_bad_options_are_one_sentence_and_exit_2(tmp_path):
    r = _run("--frames", "0")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "--frames" in r.stderr
    r = _run("--peers-python", str(tmp_path / "nope" / "python"))
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "make bench-peers" in r.stderr
