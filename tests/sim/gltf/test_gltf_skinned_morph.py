"""Morph targets on skinned glTF models (glTF 2.0 §3.7.2.2 with §3.7.3 skins and
§3.11 weights animations): kept by the importer, written by the exporter, and
played ``skin ∘ morph``. Every file is built here (no shared assets)."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from gltf_testutil import GltfBuilder, box_triangles, skin_positions, stacked_box_character, write_glb
from tiny_characters import tiny_morphed

from sim import math3d
from sim.errors import AssetError
from sim.gltf.load import load_gltf
from sim.gltf.write import save_glb
from sim.skinning import morph, skin_morph


def _load_quiet(path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "weights ignored" warning any more (nor another)
        return load_gltf(path)


def test_round_trip_keeps_targets_default_weights_names_and_weight_channels(tmp_path):
    a = tiny_morphed()
    save_glb(a, tmp_path / "m.glb")
    b = _load_quiet(tmp_path / "m.glb")
    ma, mb = a.mesh.morph, b.mesh.morph
    assert mb.names == ma.names and mb.n_targets == 4
    np.testing.assert_allclose(mb.default_weights, ma.default_weights, atol=1e-7)
    np.testing.assert_allclose(mb.positions, ma.positions, atol=1e-6)
    np.testing.assert_allclose(mb.normals, ma.normals, atol=1e-6)
    np.testing.assert_allclose(b.mesh.positions, a.mesh.positions, atol=1e-6)  # the mesh at its default weights
    assert list(b.clips) == ["bend", "twist"]
    interp = {n: [c.interpolation for c in b.clips[n].channels if c.path == "weights"] for n in b.clips}
    assert interp == {"bend": ["LINEAR"], "twist": ["CUBICSPLINE"]}  # one channel per clip over the 4 targets
    for name, ca in a.clips.items():
        cb = b.clips[name]
        assert cb.duration == pytest.approx(ca.duration) and cb.loop == ca.loop
        t = np.linspace(0.0, ca.duration, 41)
        np.testing.assert_allclose(cb.morph_weights(mb, t), ca.morph_weights(ma, t), atol=1e-6)
        for tt in t[::8]:
            pa, _ = skin_morph(a.mesh, ca.skinning_matrices(a.skeleton, [tt])[0], ca.morph_weights(ma, [tt])[0])
            pb, _ = skin_morph(b.mesh, cb.skinning_matrices(b.skeleton, [tt])[0], cb.morph_weights(mb, [tt])[0])
            assert np.abs(pa - pb).max() < 1e-5


def test_character_without_targets_stays_without(tmp_path):
    save_glb(stacked_box_character(), tmp_path / "plain.glb")
    ch = _load_quiet(tmp_path / "plain.glb")
    assert ch.mesh.morph is None
    assert not any(c.path == "weights" for clip in ch.clips.values() for c in clip.channels)


def _skinned_morph_file(tmp_path, interp="STEP", counts=(2, 2), weights_per_key=2):
    """A bone skinning a quad with two targets (default weights 0.5, 0), animated by a
    weights channel and a rotation; a second, rigid node (scaled 2, moved) with one target."""
    b = GltfBuilder()
    p, i = box_triangles()
    d0 = np.zeros_like(p)
    d0[:, 2] = 1.0  # target 0: push along +z
    n0 = np.zeros_like(p)
    n0[:, 0] = 0.5
    d1 = np.zeros_like(p)
    d1[2:, 1] = 0.5  # target 1: lift the top edge
    joints = np.zeros((4, 4), np.uint16)
    wts = np.tile(np.array([1, 0, 0, 0], np.float32), (4, 1))
    nrm = np.tile(np.array([0, 0, 1], np.float32), (4, 1))

    def prim(nt):
        tg = [{"POSITION": b.acc(d0, "VEC3"), "NORMAL": b.acc(n0, "VEC3")}, {"POSITION": b.acc(d1, "VEC3")}][:nt]
        return {"attributes": {"POSITION": b.acc(p, "VEC3"), "NORMAL": b.acc(nrm, "VEC3"), "JOINTS_0": b.acc(joints, "VEC4"),
                               "WEIGHTS_0": b.acc(wts, "VEC4")}, "indices": b.acc(i, "SCALAR"), "targets": tg}

    rigid = {"attributes": {"POSITION": b.acc(p, "VEC3")}, "indices": b.acc(i, "SCALAR"),
             "targets": [{"POSITION": b.acc(d1, "VEC3")}]}
    times = np.array([0.0, 0.5, 1.0], np.float32)
    w = np.array([[0.0, 0.0], [1.0, 0.5], [0.25, 1.0]], np.float32)[:, :weights_per_key]
    out = np.stack([np.zeros_like(w), w, np.zeros_like(w)], 1) if interp == "CUBICSPLINE" else w
    rot = np.stack([math3d.quat_from_axis_angle([0, 1, 0], a) for a in (0.0, 0.4, 0.8)]).astype(np.float32)
    b.gltf.update({
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [{"name": "bone"}, {"name": "skinned", "mesh": 0, "skin": 0},
                  {"name": "prop", "mesh": 1, "translation": [3, 0, 0], "scale": [2, 2, 2], "weights": [0.5]}],
        "meshes": [{"primitives": [prim(counts[0]), prim(counts[1])], "weights": [0.5, 0.0],
                    "extras": {"targetNames": ["push", "lift"]}},
                   {"primitives": [rigid]}],
        "skins": [{"joints": [0]}],
        "animations": [{"name": "go", "extras": {"loop": False}, "channels": [{"sampler": 0, "target": {"node": 1, "path": "weights"}},
                                                   {"sampler": 1, "target": {"node": 0, "path": "rotation"}}],
                        "samplers": [{"input": b.acc(times, "SCALAR", min=[0.0], max=[1.0]),
                                      "output": b.acc(out.ravel(), "SCALAR"), "interpolation": interp},
                                     {"input": b.acc(times, "SCALAR", min=[0.0], max=[1.0]),
                                      "output": b.acc(rot, "VEC4"), "interpolation": "LINEAR"}]}],
    })
    return write_glb(tmp_path / "sm.glb", *b.finish()), p, d0, n0, d1, w, rot


@pytest.mark.parametrize("interp", ["LINEAR", "STEP", "CUBICSPLINE"])
def test_hand_built_skinned_morph_plays_skin_of_morph(tmp_path, interp):
    path, p, d0, n0, d1, w, rot = _skinned_morph_file(tmp_path, interp)
    ch = _load_quiet(path)
    mt = ch.mesh.morph
    # two primitives of the skinned node (4 + 4 vertices) then the rigid prop (4 vertices)
    assert ch.mesh.n_vertices == 12 and mt.n_targets == 3
    assert mt.names == ["skinned.push", "skinned.lift", "prop.target0"]
    np.testing.assert_allclose(mt.default_weights, [0.5, 0.0, 0.5])
    np.testing.assert_allclose(mt.positions[0, :8], np.vstack([d0, d0]))
    np.testing.assert_allclose(mt.positions[0, 8:], 0.0)
    np.testing.assert_allclose(mt.normals[0, :4], n0)
    np.testing.assert_allclose(mt.positions[2, 8:], 2.0 * d1, atol=1e-6)  # the prop's scale moves its deltas
    np.testing.assert_allclose(mt.positions[2, :8], 0.0)
    # the mesh itself is at the default weights
    np.testing.assert_allclose(ch.mesh.positions[:4], p + 0.5 * d0, atol=1e-6)
    np.testing.assert_allclose(ch.mesh.positions[8:], 2.0 * (p + 0.5 * d1) + [3, 0, 0], atol=1e-6)
    clip = ch.clips["go"]
    assert clip.duration == pytest.approx(1.0)
    for k, t in enumerate((0.0, 0.5, 1.0)):  # at the key times every interpolation gives the key
        W = clip.morph_weights(mt, [t])[0]
        np.testing.assert_allclose(W, [w[k, 0], w[k, 1], 0.5], atol=1e-6)
        mats = clip.skinning_matrices(ch.skeleton, [t])[0]
        got, _ = skin_morph(ch.mesh, mats, W)
        R = math3d.quat_to_matrix(rot[k].astype(np.float64))
        want_skinned = (p + w[k, 0] * d0 + w[k, 1] * d1) @ R.T
        np.testing.assert_allclose(got[:4], want_skinned, atol=1e-5)
        np.testing.assert_allclose(got[8:], 2.0 * (p + 0.5 * d1) + [3, 0, 0], atol=1e-5)  # the prop: default weight
        # morph alone is the glTF sum; LBS of it is the skinned result
        mp, _ = morph(ch.mesh, W)
        np.testing.assert_allclose(skin_positions(type(ch.mesh)(mp.astype(np.float32), ch.mesh.indices,
                                                                joints=ch.mesh.joints, weights=ch.mesh.weights),
                                                  mats), got, atol=1e-5)
    if interp == "STEP":  # holds the earlier key
        np.testing.assert_allclose(clip.morph_weights(mt, [0.49])[0, :2], w[0], atol=1e-7)


def test_weights_channel_with_wrong_width_is_an_asset_error(tmp_path):
    path, *_ = _skinned_morph_file(tmp_path, weights_per_key=1)
    with pytest.raises(AssetError, match=r"sm\.glb: animations\[0\]"):
        load_gltf(path)


def test_primitives_with_different_target_counts_load_with_zero_deltas(tmp_path):
    """glTF asks every primitive of a mesh for the same number of targets; a file that breaks this still loads
    (the shorter primitive's missing target moves nothing), and crowd info's notes say so."""
    path, *_ = _skinned_morph_file(tmp_path, counts=(2, 1))
    ch = load_gltf(path)
    mt = ch.mesh.morph
    assert mt is not None and mt.names[:2] == ["skinned.push", "skinned.lift"]  # two targets on the skinned mesh
    assert np.isfinite(mt.positions).all() and np.abs(mt.positions[1]).sum() > 0  # the longer primitive's target
    assert any("different numbers of morph targets (1, 2)" in n for n in ch.notes)
