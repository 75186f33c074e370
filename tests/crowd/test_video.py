"""``crowd run --video`` / ``[output] video``: an H.264 MP4 of every frame beside the PNGs, decoded back with
imageio-ffmpeg (frame count, size, frame k against the PNG of frame k), padded odd sizes, atomic writes."""
import numpy as np
import pytest

from crowd.video import VideoWriter, even_size, pad_even, read_video, video_writer
from crowd_testutil import run_cli, tiny_scene
from crowd.images import read_png

#: PSNR bound (dB) of a decoded frame against its PNG: x264 at CRF 12 in yuv420p (half-resolution chroma) on the
#: tiny scene's 64x48 frames measured 37.5-39.6 dB; 35 dB leaves room for encoder versions, and a wrong frame (the
#: neighbour) measures far less on a moving camera (asserted too)
MIN_PSNR = 35.0


def psnr(a, b) -> float:
    mse = ((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2).mean()
    return float("inf") if mse == 0 else 10.0 * np.log10(255.0 ** 2 / mse)


MOVING = {'position = [1.0, 2.0, 7.0]\ntarget = [1.0, 0.8, 1.0]\n':
          'keys = [{ time = 0.0, position = [1.0, 2.0, 7.0], target = [1.0, 0.8, 1.0] },\n'
          '        { time = 0.5, position = [5.0, 3.0, 5.0], target = [1.0, 0.8, 1.0] }]\n'}


def test_run_video_decodes_to_the_frames_pngs(tmp_path, write_scene):
    scene = write_scene(tiny_scene(replace={"frames = 3": "frames = 8", **MOVING}))
    out = tmp_path / "out"
    r = run_cli("run", scene, "--video", "--out", out, "--quiet")
    assert r.returncode == 0, r.stderr
    frames, (w, h) = read_video(out / "video.mp4")
    assert (w, h) == (64, 48) and frames.shape == (8, 48, 64, 3)
    pngs = [read_png(out / "frames" / f"frame_{k:05d}.png") for k in range(8)]
    for k in range(8):
        assert psnr(frames[k], pngs[k]) >= MIN_PSNR, k
    for k in range(7):  # frame k is frame k, not its neighbour
        assert psnr(frames[k], pngs[k]) > psnr(frames[k], pngs[k + 1]) + 3.0, k
    assert not list(out.glob(".*"))  # no temporary file left beside it


def test_output_video_key_writes_every_frame_not_only_png_ones(tmp_path, write_scene):
    scene = write_scene(tiny_scene(replace={"frames = 3": "frames = 5", "png_every = 1": "png_every = 2"},
                                   append="\n[output]\nvideo = true\n"))
    out = tmp_path / "out"
    r = run_cli("run", scene, "--out", out, "--quiet")
    assert r.returncode == 0, r.stderr
    frames, _ = read_video(out / "video.mp4")
    assert frames.shape[0] == 5 and len(list((out / "frames").glob("*.png"))) == 3
    for k in (0, 2, 4):
        assert psnr(frames[k], read_png(out / "frames" / f"frame_{k:05d}.png")) >= MIN_PSNR


def test_odd_size_is_padded_by_one_pixel(tmp_path, write_scene):
    scene = write_scene(tiny_scene(replace={"frames = 3": "frames = 2"}))
    out = tmp_path / "out"
    r = run_cli("run", scene, "--video", "--size", "65x49", "--out", out, "--quiet")
    assert r.returncode == 0, r.stderr
    frames, (w, h) = read_video(out / "video.mp4")
    assert (w, h) == (66, 50) and frames.shape[0] == 2
    png = read_png(out / "frames" / "frame_00001.png")
    assert png.shape == (49, 65, 3)
    assert psnr(frames[1][:49, :65], png) >= MIN_PSNR


def test_pad_even_repeats_the_last_row_and_column():
    px = np.arange(3 * 5 * 3, dtype=np.uint8).reshape(3, 5, 3)
    p = pad_even(px)
    assert p.shape == (4, 6, 3) and (p[:3, :5] == px).all()
    assert (p[3, :5] == px[2]).all() and (p[:3, 5] == px[:, 4]).all()
    assert pad_even(p) is p and even_size((65, 49)) == (66, 50)


def test_no_half_written_mp4_after_an_error(tmp_path):
    target = tmp_path / "v.mp4"
    frame = np.zeros((16, 16, 3), np.uint8)
    with pytest.raises(RuntimeError):
        with video_writer(target, (16, 16), 30.0) as v:
            v.write(frame)
            v.write(frame)
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []
    w = VideoWriter(target, (16, 16), 30.0)
    with pytest.raises(ValueError, match="expected"):
        w.write(np.zeros((8, 8, 3), np.uint8))  # the wrong size is refused, not encoded
    w.abort()
    w.abort()  # safe twice
    assert list(tmp_path.iterdir()) == []


def test_run_interrupted_mid_video_leaves_no_output(tmp_path, write_scene, monkeypatch):
    """An error while the video is being written: neither the run folder nor any mp4 remains."""
    from crowd.engine import Engine
    from crowd.scene import load_scene

    scene = load_scene(write_scene(tiny_scene(replace={"frames = 3": "frames = 4"})))
    out = tmp_path / "out"
    calls = {"n": 0}
    with Engine(scene.with_overrides(video=True, out=out), quiet=True) as engine:
        renderer = engine._open_renderer()
        real = renderer.read_pixels

        def failing():
            calls["n"] += 1
            if calls["n"] == 5:  # mid-run (PNG and video both read pixels)
                raise RuntimeError("disk full")
            return real()

        monkeypatch.setattr(renderer, "read_pixels", failing)
        with pytest.raises(RuntimeError, match="disk full"):
            engine.run()
    assert not out.exists()
    assert not list(tmp_path.rglob("*.mp4"))
    assert [p.name for p in tmp_path.iterdir()] == ["scene.toml"]
