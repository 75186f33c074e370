"""Baking skinned clips within what the renderer holds, and refusing animation it cannot draw (issue 20).

A character's joint table has one texture row per baked frame of all its clips; at most BAKE_MAX_FRAMES
(GL 4.5's smallest GL_MAX_TEXTURE_SIZE). Two 60 s clips at 240 fps need 28,802: they used to fail at upload
with a ValueError traceback; they are now baked at a lower rate. Skinned positions beyond float32 are an
AssetError naming the file, not a ValueError, and never reach the GPU."""
import numpy as np
import pytest
from awkward_gltf import clip_of, exploding

from lod.full.reps import BAKE_MAX_FRAMES, bake_intervals, build_rep
from sim.errors import AssetError
from sim.gltf.load import load_gltf
from sim.skinning import skin


def test_bake_intervals():
    assert bake_intervals([1.0, 0.7, 0.0], 30).tolist() == [30, 21, 1]  # round(d * fps), at least 1
    n = bake_intervals([60.0, 60.0], 240)
    assert (n + 1).sum() <= BAKE_MAX_FRAMES and n[0] == n[1] and n[0] > 8000  # one lower rate for every clip
    n = bake_intervals([600.0, 0.1, 0.0], 30, max_frames=1000)
    assert (n + 1).sum() <= 1000 and n.tolist()[1:] == [1, 1] and n[0] >= 990
    with pytest.raises(ValueError, match="clips need at least"):
        bake_intervals(np.ones(600), 30, max_frames=1000)


def test_two_long_clips_at_240_fps_fit_the_joint_texture(tmp_path):
    ch = load_gltf(clip_of(tmp_path / "long.glb", 60.0, n_clips=2))
    rep = build_rep(ch, fps=240)
    assert rep.joint_table.shape[0] == rep.clip_frames.sum() <= BAKE_MAX_FRAMES
    np.testing.assert_allclose(rep.clip_fps, (rep.clip_frames - 1) / 60.0)
    assert rep.clip_fps.min() > 130  # still far finer than the 5 keys of the clip
    # the baked frames are the clip's poses at their times (the last frame at t = duration)
    f = rep.frame_coordinate(np.array([1, 1]), np.array([0.0, 59.999999]))
    assert f[0] == rep.clip_offset[1] and f[1] == pytest.approx(rep.clip_offset[1] + rep.clip_frames[1] - 1)
    k = int(rep.clip_offset[1]) + 1234
    t = 1234 / rep.clip_fps[1]
    want = ch.clip(1).skinning_matrices(ch.skeleton, [t])[0][:, :3, :]
    np.testing.assert_allclose(rep.joint_table[k], want, atol=1e-5)
    assert rep.frame_aabb.shape[0] == rep.joint_table.shape[0]
    p = skin(ch.mesh, ch.clip(1).skinning_matrices(ch.skeleton, [t])[0])[0]
    assert (p >= rep.frame_aabb[k, 0] - 1e-5).all() and (p <= rep.frame_aabb[k, 1] + 1e-5).all()


def test_animation_beyond_float32_is_an_asset_error_naming_the_file(tmp_path):
    ch = load_gltf(exploding(tmp_path / "boom.glb"))
    with pytest.raises(AssetError, match=r"^boom\.glb: clip 'boom': skinned positions are NaN or beyond the "
                                         r"float32 range; [^\n]*$"):
        build_rep(ch)
