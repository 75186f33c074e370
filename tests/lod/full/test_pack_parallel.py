"""The parallel passes of lod/full/pack.py (used from PACK_PARALLEL_MIN instances) give
bit-identical instance batches to the serial ones, including culled, coincident and
non-finite agents, and several draw groups."""
import numpy as np
import pytest

from lod.full import pack
from lod.view import Camera


@pytest.mark.parametrize("cull", [True, False])
def test_parallel_instance_batches_equal_the_serial_ones(monkeypatch, cull):
    rng = np.random.default_rng(11)
    n, G = 20_011, 5
    pos = np.c_[rng.uniform(-300, 300, n), rng.uniform(-1, 1, n), rng.uniform(-300, 300, n)] + [1e6, 0.0, -2e6]
    pos[:9] = pos[0]  # coincident agents
    heading = rng.uniform(-7, 7, n)
    heading[13] = np.nan
    scale = rng.uniform(0.5, 2.0, n)
    gid = rng.integers(0, G, n).astype(np.int64)
    t = rng.uniform(-5, 20, n)
    t[17] = np.inf
    anim = rng.uniform(0, 1, n)
    g_sphere = np.c_[rng.uniform(-1, 1, (G, 3)), rng.uniform(0.5, 2, G)]
    g_skinned = np.array([True, False, True, True, False])
    g_off = np.array([0.0, 0.0, 30.0, 61.0, 0.0])
    g_fps = np.full(G, 30.0)
    g_dur = np.array([1.0, 0.0, 1.0, 2.5, 0.0])
    g_loop = np.array([True, False, False, True, False])
    g_last = g_off + g_fps * g_dur
    cam = Camera.look_at((1e6, 40.0, -2e6 + 350.0), (1e6, 0.0, -2e6))
    origin = np.asarray(cam.position, np.float64)
    planes = cam.frustum_planes(16 / 9)
    args = (pos, origin, heading, scale, gid, t, anim, g_sphere, g_skinned, g_off, g_fps, g_dur, g_loop, g_last,
            planes, cull)
    monkeypatch.setattr(pack, "PACK_PARALLEL_MIN", 10 ** 9)
    serial = pack.instance_batches(*args)
    monkeypatch.setattr(pack, "PACK_PARALLEL_MIN", 1)
    par = pack.instance_batches(*args)
    assert serial[0].shape[0] > 1000 and (not cull or serial[0].shape[0] < n)
    for a, b in zip(serial, par):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    ref = pack.instance_batches_numpy(*args)
    assert np.array_equal(ref[0], par[0]) and np.array_equal(ref[2], par[2])


def test_parallel_locate_equals_the_serial_one(monkeypatch):
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "fixtures"))
    from tiny_characters import tiny_keyframed

    from lod.full import reps as full_reps

    krep = full_reps.build_rep(tiny_keyframed())
    t = np.random.default_rng(2).uniform(-10, 40, 5001)
    t[3], t[4] = np.nan, np.inf
    monkeypatch.setattr(full_reps, "LOCATE_PARALLEL_MIN", 10 ** 9)
    serial = krep.locate(0, t)
    monkeypatch.setattr(full_reps, "LOCATE_PARALLEL_MIN", 1)
    par = krep.locate(0, t)
    for a, b in zip(serial, par):
        assert np.array_equal(a, b)
    for a, b in zip(par, krep.locate_numpy(0, t)):
        assert np.array_equal(a, b) or np.allclose(a, b, rtol=0, atol=1e-12)
