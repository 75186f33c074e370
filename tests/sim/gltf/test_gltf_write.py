"""glTF 2.0 export (sim.gltf.write): round trips through sim.gltf.load.

Shared helpers (hand-built characters, round-trip checks, real models):
gltf_testutil.py.
"""
from __future__ import annotations

import numpy as np
import pytest

from gltf_testutil import (
    ASSET_EXPECT,
    _load_asset,
    assert_round_trip,
    box_triangles,
    needs_keyframes,
    skin_positions,
    stacked_box_character,
)

from sim.character import KeyframedCharacter
from sim.errors import AssetError
from sim.gltf.load import load_gltf
from sim.gltf.write import save_glb
from sim.mesh import Mesh


# --------------------------------------------------------------------------- round trips


def test_round_trip_hand_built_skinned(tmp_path):
    ch = stacked_box_character()
    out = tmp_path / "box3.glb"
    save_glb(ch, out)
    back = load_gltf(out)
    assert back.kind == "skinned"
    assert_round_trip(ch, back)
    # and the skinned result agrees at a few times
    for clip in ch.clips.values():
        for t in (0.1, 0.5, 0.9):
            pa = skin_positions(ch.mesh, clip.skinning_matrices(ch.skeleton, [t])[0])
            pb = skin_positions(back.mesh, back.clips[clip.name].skinning_matrices(back.skeleton, [t])[0])
            np.testing.assert_allclose(pb, pa, atol=1e-5)
    assert not list(tmp_path.glob("*.tmp"))  # atomic write leaves no temp file


def test_round_trip_identity_root(tmp_path):
    ch = stacked_box_character(with_root=False)
    save_glb(ch, tmp_path / "a.glb")
    assert_round_trip(ch, load_gltf(tmp_path / "a.glb"))


def test_round_trip_procedural_humanoid(tmp_path):
    procedural = pytest.importorskip("sim.procedural", reason="sim.procedural (engineer A) not present yet")
    if not hasattr(procedural, "humanoid"):
        pytest.skip("sim.procedural.humanoid (engineer A) not present yet")
    ch = procedural.humanoid(triangles=2000, seed=1)
    save_glb(ch, tmp_path / "h.glb")
    back = load_gltf(tmp_path / "h.glb")
    assert back.skeleton.n_joints == ch.skeleton.n_joints
    assert_round_trip(ch, back)


@needs_keyframes
def test_round_trip_keyframed(tmp_path):
    from sim import keyframes

    p, i = box_triangles()
    meshes = []
    for k in range(4):
        q = p.astype(np.float64).copy()
        q[2:, 2] = 0.25 * k  # fold the quad
        m = Mesh(positions=q.astype(np.float32), indices=i.reshape(-1, 3), colors=np.tile([0.1 * k, 0.5, 0.2, 1.0], (4, 1)).astype(np.float32))
        m.ensure_normals()
        meshes.append(m)
    times = np.array([0.0, 0.2, 0.5, 0.7])
    anim = keyframes.from_meshes("fold", times, meshes, loop=True, duration=1.0)
    anim2 = keyframes.from_meshes("once", np.array([0.0, 1.0]), meshes[:2], loop=False)
    ch = KeyframedCharacter(name="quad", animations={"fold": anim, "once": anim2})
    save_glb(ch, tmp_path / "q.glb")
    back = load_gltf(tmp_path / "q.glb")
    assert back.kind == "keyframed" and back.clip_names() == ["fold", "once"]
    for a in (anim, anim2):
        b = back.animations[a.name]
        assert b.loop == a.loop
        assert b.duration == pytest.approx(a.duration, abs=1e-6)
        np.testing.assert_allclose(b.times, a.times, atol=1e-6)
        assert len(b.keyframes) == len(a.keyframes)
        for ka, kb in zip(a.keyframes, b.keyframes):
            np.testing.assert_allclose(kb.positions, ka.positions, atol=1e-6)
            np.testing.assert_allclose(kb.colors, ka.colors, atol=1e-6)
            np.testing.assert_array_equal(kb.indices, ka.indices)


@needs_keyframes
def test_export_keyframed_rejects_mixed_topology(tmp_path):
    from sim import keyframes

    p, i = box_triangles()
    m1 = Mesh(positions=p, indices=i.reshape(-1, 3))
    m2 = Mesh(positions=p[:3], indices=i[:3].reshape(-1, 3))
    for m in (m1, m2):
        m.ensure_normals()
    corr = keyframes.Correspondence(pairs=np.array([[0, 0], [1, 1], [2, 2]]), vanish=[(1, 2)])
    anim = keyframes.from_meshes("shrink", np.array([0.0, 1.0]), [m1, m2], correspondences=[corr], loop=False)
    with pytest.raises(AssetError, match="topology"):
        save_glb(KeyframedCharacter(name="x", animations={"shrink": anim}), tmp_path / "x.glb")
    assert not (tmp_path / "x.glb").exists()


@pytest.mark.parametrize("name", list(ASSET_EXPECT))
def test_asset_export_round_trip(name, tmp_path):
    ch = _load_asset(name)
    save_glb(ch, tmp_path / name)
    back = load_gltf(tmp_path / name)
    assert back.kind == ch.kind and back.clip_names() == ch.clip_names()
    if ch.kind == "skinned":
        assert_round_trip(ch, back)
    else:
        for n, a in ch.animations.items():
            b = back.animations[n]
            assert len(b.keyframes) == len(a.keyframes) and b.loop == a.loop
            assert b.duration == pytest.approx(a.duration, abs=1e-6)
            for ka, kb in zip(a.keyframes, b.keyframes):
                np.testing.assert_allclose(kb.positions, ka.positions, atol=1e-4)  # float32 deltas of ~100-unit models
