"""Importing the characters people bring (issue 20): a rig mixing skinned and rigid parts with two skins and
weights summing to 1.8, a statue without animation, a joint chain 100 deep, 64 primitives in one mesh, and
clips of 0.1 s and 60 s. What the importer repairs or makes up is said in ``notes`` and by ``crowd info``."""
import numpy as np
import pytest
from awkward_gltf import clip_of, deep_chain, many_primitives, mixed_rig, statue
from crowd_testutil import run_cli

from sim.describe import describe
from sim.gltf.load import load_gltf
from sim.skinning import skin


def _rigid_vertices(ch, names):
    js = [ch.skeleton.names.index(n) for n in names]
    return np.isin(ch.mesh.joints[:, 0], js) & (ch.mesh.weights[:, 0] == 1.0)


def test_mixed_rig_weights_normalised_and_noted(tmp_path):
    ch = load_gltf(mixed_rig(tmp_path / "mixed.glb"))
    assert ch.skeleton.names == ["hip", "spine", "head", "arm", "hand", "helmet", "sword", "shield"]
    np.testing.assert_allclose(ch.mesh.weights.sum(1), 1.0, atol=1e-6)
    rigid = _rigid_vertices(ch, ["helmet", "sword", "shield"])
    assert rigid.sum() == 24 + 27 + 4  # the rigid parts' own vertices: weight 1 in the file, not counted
    skinned = ch.mesh.n_vertices - int(rigid.sum())
    assert ch.notes == [f"skin weights normalised on {skinned} vertices (sums 1.8)"]
    assert describe(ch)["notes"] == ch.notes
    # the normalised weights skin like the file's weights divided by their sum: rest pose = bind pose here
    rest, _ = skin(ch.mesh, ch.skeleton.skinning_matrices(*ch.skeleton.rest_pose()))
    np.testing.assert_allclose(rest[~rigid], ch.mesh.positions[~rigid], atol=1e-5)


def test_mixed_rig_rigid_parts_follow_their_animated_joints(tmp_path):
    """The helmet moves rigidly with the head joint; the sword slides along the hand (its own node animation)."""
    ch = load_gltf(mixed_rig(tmp_path / "mixed.glb"))
    clip = ch.clip("swing")
    sk = ch.skeleton
    t = np.array([0.0, 0.4, 1.1])
    mats = clip.skinning_matrices(sk, t)
    helmet = _rigid_vertices(ch, ["helmet"])
    head = sk.names.index("head")
    for m in mats:
        p, _ = skin(ch.mesh, m)
        ref = (m[head] @ np.c_[ch.mesh.positions[helmet], np.ones(helmet.sum())].T).T[:, :3]
        np.testing.assert_allclose(p[helmet], ref, atol=1e-5)
    sword = _rigid_vertices(ch, ["sword"])
    hand = sk.names.index("hand")
    rel = [np.linalg.inv(sk.global_matrices(*clip.sample_times(sk, [x]))[0, hand]) for x in t]
    local = [(r @ np.c_[skin(ch.mesh, m)[0][sword], np.ones(sword.sum())].T).T[:, 0] for r, m in zip(rel, mats)]
    assert abs(local[1].mean() - local[0].mean()) > 0.05  # slid along the blade (x in the hand's frame)


def test_statue_without_animation_gets_a_constant_rest_clip(tmp_path):
    ch = load_gltf(statue(tmp_path / "statue.glb"))
    assert ch.clip_names() == ["rest"]
    clip = ch.clip("rest")
    assert clip.duration == 1.0 and clip.loop and [c.times.size for c in clip.channels] == [1]
    rest, _ = skin(ch.mesh, ch.skeleton.skinning_matrices(*ch.skeleton.rest_pose()))
    for m in clip.skinning_matrices(ch.skeleton, [0.0, 0.37, 5.2]):
        np.testing.assert_allclose(skin(ch.mesh, m)[0], rest, atol=1e-6)
    d = describe(ch)
    assert d["clips"] == [{"name": "rest", "duration": 1.0, "keys": 1, "loop": True}]
    assert d["notes"] == ["no animation: one constant clip 'rest' (1 s) holds the rest pose"]
    np.testing.assert_allclose(d["bounds"]["animated"]["size"], [0.6, 1.8, 0.6], atol=1e-6)


def test_crowd_info_says_what_was_repaired(tmp_path):
    r = run_cli("info", mixed_rig(tmp_path / "mixed.glb"))
    assert r.returncode == 0, r.stderr
    assert "  note: skin weights normalised on 325 vertices (sums 1.8)" in r.stdout.splitlines()
    r = run_cli("info", statue(tmp_path / "statue.glb"))
    assert r.returncode == 0, r.stderr
    assert "  note: no animation: one constant clip 'rest' (1 s) holds the rest pose" in r.stdout.splitlines()
    r = run_cli("info", clip_of(tmp_path / "clean.glb", 1.0))
    assert r.returncode == 0 and "note:" not in r.stdout  # nothing repaired, nothing said


def test_deep_chain_and_many_primitives_import(tmp_path):
    ch = load_gltf(deep_chain(tmp_path / "deep.glb", depth=100))
    sk = ch.skeleton
    assert sk.n_joints == 100 and list(sk.parents) == [-1] + list(range(99))
    p, _ = skin(ch.mesh, ch.clip("curl").skinning_matrices(sk, [0.25])[0])
    assert np.isfinite(p).all()
    top = ch.mesh.positions[:, 1] > 1.99
    assert np.linalg.norm(p[top] - ch.mesh.positions[top], axis=1).min() > 0.5  # the tip curled (1.8 deg x 100)
    ch = load_gltf(many_primitives(tmp_path / "many.glb", n=64))
    assert ch.mesh.n_triangles == 64 * 12 and ch.mesh.n_vertices == 64 * 24 and ch.notes == []


@pytest.mark.parametrize("duration", [0.1, 60.0])
def test_short_and_long_clips_keep_their_duration(tmp_path, duration):
    ch = load_gltf(clip_of(tmp_path / "c.glb", duration))
    assert ch.clip("bend").duration == pytest.approx(duration)
    m = ch.clip("bend").skinning_matrices(ch.skeleton, [0.25 * duration, 0.75 * duration])
    p0, p1 = (skin(ch.mesh, x)[0] for x in m)
    assert np.abs(p0 - p1).max() > 0.3  # bent one way, then the other
