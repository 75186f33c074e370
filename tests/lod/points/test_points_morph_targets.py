"""Mode points bakes morph targets (glTF 2.0 §3.7.2.2) into its keyframes: every
keyframe of a skinned character with morph targets is the CPU ``skin ∘ morph``
pose at its time, and so are the segment ends the point hierarchies are built
from (Wand & Straßer §3)."""
import numpy as np
import pytest

from tiny_characters import tiny_morphed

from lod.full.reps import build_keyframed_rep
from lod.points.mode import build_points_rep, keyframed_character, segment_arrays
from lod.points.rep import HierarchyCache
from sim.skinning import skin, skin_morph


@pytest.fixture(scope="module")
def ch():
    return tiny_morphed()


def _reference(ch, name, t):
    clip = ch.clips[name]
    mats = clip.skinning_matrices(ch.skeleton, [t])[0]
    return skin_morph(ch.mesh, mats, clip.morph_weights(ch.mesh.morph, [t])[0])[0], skin(ch.mesh, mats)[0]


def test_keyframes_are_skin_morph_at_the_key_times(ch):
    kfc = keyframed_character(ch, 9)
    assert list(kfc.animations) == ["bend", "twist"]
    moved = 0.0
    for name, anim in kfc.animations.items():
        assert len(anim.keyframes) == 9
        for t, kf in zip(anim.times, anim.keyframes):
            want, unmorphed = _reference(ch, name, t)
            assert np.abs(kf.positions - want).max() < 1e-6, (name, t)
            moved = max(moved, float(np.abs(want - unmorphed).max()))
    assert moved > 0.2  # the morphs are in the poses, not only the skeleton


def test_point_hierarchies_are_built_from_the_morphed_segment_ends(ch, tmp_path):
    rep = build_points_rep(ch, "m", {"keyframes": 5}, cache=HierarchyCache(tmp_path), clips=["twist"])
    kf = rep.keyframed
    a0, ns = int(kf.anim_first_seg[1]), int(kf.anim_n_segs[1])
    for s in range(a0, a0 + ns):
        p0, p1, *_ = segment_arrays(kf, s)
        for p, t in ((p0, kf.seg_start[s]), (p1, kf.seg_end[s])):
            want, _ = _reference(ch, "twist", t)
            assert np.abs(p - want).max() < 1e-6, (s, t)
    assert len(rep.hierarchies) == kf.n_parts
    assert build_keyframed_rep(keyframed_character(ch, 5)).n_parts == kf.n_parts
