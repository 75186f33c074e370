"""The true reference (crowd/reference.py): full detail with K x K samples per pixel, box-filtered, tiled where
the GL limits ask; it converges, differs from the aliased frame only along edges, and tiles change nothing."""
import math

import numpy as np
import pytest
from crowd_testutil import tiny_scene

from crowd.errors import CrowdError
from crowd.reference import (DEFAULT_K, TileRenderer, box_filter, check_fits, check_k, draw_tiles, plan_tiles,
                             reference_frames, tile_projection)
from crowd.scene import load_scene
from lod.drawlist import DrawBatch, DrawList
from lod.full.reps import StaticRep
from lod.view import Camera
from render.renderer import Renderer


@pytest.fixture(scope="module")
def gl_ctx():
    from render.context import create_context

    ctx = create_context()
    yield ctx
    ctx.release()


def _psnr(a, b) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return math.inf if mse == 0 else 10.0 * math.log10(255.0 ** 2 / mse)


# ---------------------------------------------------------------------------------------------------- pieces
def test_box_filter_is_the_rounded_block_mean():
    img = np.zeros((4, 6, 3), np.uint8)
    img[:2, :2] = [[[255, 0, 1]] * 2, [[255, 0, 2]] * 2]
    img[2:, 4:] = 10
    img[2, 4, 0] = 11  # mean 10.25 -> 10
    img[0, 2:4, 1] = [1, 2]  # mean 0.75 -> 1
    out = box_filter(img, 2)
    assert out.shape == (2, 3, 3) and out.dtype == np.uint8
    assert out[0, 0].tolist() == [255, 0, 2]  # mean 1.5 rounds half up
    assert out[1, 2].tolist() == [10, 10, 10] and out[0, 1, 1] == 1
    with pytest.raises(ValueError, match="multiple"):
        box_filter(np.zeros((5, 4, 3), np.uint8), 2)


def test_plan_tiles_fits_the_limits_and_covers_the_frame():
    one = plan_tiles((1280, 720), 4)
    assert one.origins == ((0, 0),) and one.tile_pixels == (5120, 2880)
    p = plan_tiles((1280, 720), 8, max_side=16384, max_pixels=1 << 25)  # 59 M pixels: tiled
    tw, th = p.tile_pixels
    assert tw <= 16384 and th <= 16384 and tw * th <= 1 << 25 and len(p.origins) > 1
    cover = np.zeros((720, 1280), int)
    for x, y in p.origins:
        cover[y:y + p.tile[1], x:x + p.tile[0]] += 1
    assert (cover == 1).all()
    odd = plan_tiles((101, 37), 3, max_side=64, max_pixels=64 * 64)  # 303 x 111 pixels in 64-pixel tiles
    assert odd.tile_pixels[0] <= 64 and odd.tile_pixels[1] <= 64
    cover = np.zeros((37 + odd.tile[1], 101 + odd.tile[0]), int)
    for x, y in odd.origins:
        cover[y:y + odd.tile[1], x:x + odd.tile[0]] += 1
    assert (cover[:37, :101] == 1).all()


def test_tile_projection_maps_the_window_onto_the_whole_clip_range():
    P = Camera().projection(16 / 9)
    T = tile_projection(P, (160, 90), (40, 30), (40, 30))  # columns 40..80, rows 30..60 (top first)
    for (x, y) in ((40, 30), (80, 60), (60, 45)):
        ndc = np.array([-1 + 2 * x / 160, 1 - 2 * y / 90])
        p = np.linalg.solve(P, np.array([ndc[0], ndc[1], 0.5, 1.0]))  # a point drawn at that pixel corner
        q = T @ p
        tx, ty = (q[0] / q[3] + 1) / 2 * 40, (1 - q[1] / q[3]) / 2 * 30
        assert (tx, ty) == pytest.approx((x - 40, y - 30), abs=1e-9)
        assert q[2] / q[3] == pytest.approx(0.5)


@pytest.mark.parametrize("bad", [1, 9, 0, -4, 2.5, "four", float("nan"), None])
def test_k_outside_the_range_is_one_sentence(bad):
    with pytest.raises(CrowdError) as e:
        check_k(bad, "--reference-samples")
    msg = str(e.value)
    assert "--reference-samples" in msg and "2 to 8" in msg and "\n" not in msg
    assert check_k(DEFAULT_K) == 4 and check_k("8") == 8


def test_a_reference_that_would_not_fit_names_what_would():
    plan = plan_tiles((1280, 720), 8, max_side=16384, max_pixels=1 << 24)
    with pytest.raises(CrowdError) as e:
        check_fits(plan, available=int(plan.bytes * 0.5))
    msg = str(e.value)
    assert msg.startswith("--reference-samples 8: the reference at 1280x720 needs") and "\n" not in msg
    assert "would fit" in msg
    with pytest.raises(CrowdError, match="no K from 2 fits"):
        check_fits(plan, available=1000)
    check_fits(plan, available=None)
    check_fits(plan, available=plan.bytes * 10)


# ---------------------------------------------------------------------------------------------------- drawing
def _flat_rep():
    """Four large flat triangles at different depths, each one colour, lit straight on (normal to the camera)."""
    tris = [((-3, -2, -8), (0, 2.5, -8), (-0.5, -2.5, -8)),
            ((0.2, -2, -6), (3, -1.5, -6), (1.5, 2, -6)),
            ((-2, 0.5, -7), (1, 1.5, -7), (-1.5, 2.2, -7)),
            ((-1, -2.2, -5), (0.8, -2.4, -5), (0, -1.0, -5))]
    pos = np.array(tris, np.float32).reshape(-1, 3)
    nrm = np.tile(np.array([0, 0, 1], np.float32), (pos.shape[0], 1))
    cols = [(0.9, 0.2, 0.2), (0.2, 0.8, 0.3), (0.2, 0.3, 0.9), (0.9, 0.9, 0.2)]
    col = np.array([[*c, 1.0] for c in cols for _ in range(3)], np.float32)
    box = np.stack([pos.min(0), pos.max(0)])
    c = box.mean(0)
    sphere = np.array([*c, float(np.linalg.norm(pos - c, axis=1).max())])
    return StaticRep("flat", pos, nrm, col, np.arange(pos.shape[0], dtype=np.uint32).reshape(-1, 3), box, sphere)


def _pixel_edge_distance(rep, cam, size) -> np.ndarray:
    """(h, w) distance in pixels from each pixel centre to the nearest projected triangle edge."""
    w, h = size
    vp = cam.projection(w / h) @ cam.view_matrix()
    p = np.c_[rep.positions.astype(np.float64), np.ones(len(rep.positions))] @ vp.T
    xy = np.c_[(p[:, 0] / p[:, 3] + 1) / 2 * w, (1 - p[:, 1] / p[:, 3]) / 2 * h]
    ys, xs = np.mgrid[0:h, 0:w] + 0.5
    q = np.stack([xs, ys], -1)
    best = np.full((h, w), np.inf)
    for t in rep.indices.reshape(-1, 3):
        for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
            A, B = xy[a], xy[b]
            d = B - A
            u = np.clip(((q - A) @ d) / max(float(d @ d), 1e-12), 0, 1)
            best = np.minimum(best, np.linalg.norm(q - (A + u[..., None] * d), axis=-1))
    return best


def test_flat_triangles_differ_from_the_aliased_frame_only_along_edges(gl_ctx):
    size, k = (96, 64), 4
    rep = _flat_rep()
    cam = Camera.look_at((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), fov_y=50.0, near=0.1, far=100.0)
    rows = np.zeros((1, 16), np.float32)
    rows[0, [0, 5, 10]] = 1.0

    def dl(sz):
        b = DrawBatch(rep.key, 0, np.zeros(1, np.int32), rows, triangles=rep.n_triangles)
        return DrawList(np.zeros(3), cam.view_matrix(), cam.projection(sz[0] / sz[1]), sz, [b])

    with Renderer(size, ctx=gl_ctx) as r:
        r.upload(rep)
        r.draw(dl(size), (0.1, 0.1, 0.12))
        aliased = r.read_pixels()
    plan = plan_tiles(size, k)
    with Renderer(plan.tile_pixels, ctx=gl_ctx) as r:
        r.upload(rep)
        ref = draw_tiles(r, dl(plan.tile_pixels), plan, (0.1, 0.1, 0.12))
    with TileRenderer(size, k, ctx=gl_ctx, reps=[rep]) as tiles:  # the benchmarks' way: the same image
        assert tiles.big == plan.tile_pixels
        assert np.array_equal(tiles.draw(dl(tiles.big), (0.1, 0.1, 0.12)), ref)
    diff = np.abs(aliased.astype(int) - ref.astype(int)).max(axis=2)
    far = _pixel_edge_distance(rep, cam, size) > 1.0 + math.sqrt(0.5)  # the whole pixel more than 1 px away
    assert far.mean() > 0.8
    assert diff[far].max() <= 1, f"{int((diff[far] > 1).sum())} interior pixels differ by more than 1/255"
    assert (diff[~far] > 1).sum() > 20  # the edges do differ: the reference is anti-aliased


TILED_SCENE = tiny_scene(replace={"size = [64, 48]": "size = [80, 48]", "frames = 3": "frames = 4"})


def test_tiles_draw_the_frame_the_whole_does(write_scene):
    scene = load_scene(write_scene(TILED_SCENE))
    whole = reference_frames(scene, [0, 3], k=4)
    assert whole["plan"].origins == ((0, 0),)
    tiled = reference_frames(scene, [0, 3], k=4, limits=(96, 96 * 64))  # 320 x 192 pixels in 96-pixel tiles
    assert len(tiled["plan"].origins) >= 4
    for f in (0, 3):
        a, b = whole["images"][f], tiled["images"][f]
        assert a.shape == b.shape == (48, 80, 3)
        assert _psnr(a, b) > 50.0, f"frame {f}: tiled {_psnr(a, b):.1f} dB from whole"
        assert a.std() > 5  # not an empty frame
    assert set(whole["seconds"]) == {0, 3} and all(s > 0 for s in whole["seconds"].values())


# a crowd whose characters are a few pixels tall: most triangles far below a pixel
SUBPIXEL_SCENE = tiny_scene(replace={"rows = 2": "rows = 24", "cols = 2": "cols = 24",
                                     "spacing = [1.5, 1.5]": "spacing = [1.2, 1.2]",
                                     "position = [1.0, 2.0, 7.0]": "position = [14.0, 9.0, 40.0]",
                                     "target = [1.0, 0.8, 1.0]": "target = [14.0, 0.0, 14.0]",
                                     "size = [64, 48]": "size = [128, 72]", "frames = 3": "frames = 1"})


def test_the_reference_converges_on_a_subpixel_crowd(write_scene):
    from crowd.engine import Engine
    from crowd.reference import reference_scene

    scene = load_scene(write_scene(SUBPIXEL_SCENE))
    r4 = reference_frames(scene, [0], k=4)["images"][0]
    r8 = reference_frames(scene, [0], k=8)["images"][0]
    with Engine(reference_scene(scene), quiet=True) as eng:
        run = eng.run(frames=1, out_dir=write_scene("", "x").parent / "aliased", png_every=1)
    from crowd.images import read_png

    aliased = read_png(run.pngs[0])
    a4, a8 = _psnr(aliased, r4), _psnr(aliased, r8)
    assert abs(a4 - a8) < 0.5, f"aliased full detail: {a4:.2f} dB against K=4, {a8:.2f} dB against K=8"
    assert _psnr(r4, r8) > a4 + 6.0  # K = 4 is much closer to K = 8 than the aliased frame is
    assert a4 < 40.0  # the crowd is sub-pixel: the aliased frame is visibly off


# ---------------------------------------------------------------------------------------------------- the cache
def test_reference_frames_are_cached_by_content(write_scene, tmp_path, monkeypatch):
    import dataclasses

    from crowd.reference_cache import cache_folder, reference_task

    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path / "cache"))
    scene = load_scene(write_scene(TILED_SCENE))
    a = reference_task(scene, [0, 2], 2)
    assert a["drawn"] == [0, 2] and a["cached"] == [] and a["tiles"] == 1
    b = reference_task(scene, [0, 2, 3], 2)  # a second report: only the new frame is drawn
    assert b["cached"] == [0, 2] and b["drawn"] == [3]
    assert all(b["files"][n] == a["files"][n] for n in a["files"])
    assert b["seconds"][0] == pytest.approx(a["seconds"][0])  # the cost it took, reported from the cache
    assert reference_task(scene, [0], 3)["drawn"] == [0]  # another K
    moved = dataclasses.replace(scene, camera=dataclasses.replace(scene.camera, position=(1.0, 2.0, 8.0)))
    assert reference_task(moved, [0], 2)["drawn"] == [0]  # another view
    out_only = scene.with_overrides(out=tmp_path / "elsewhere", frames=9, png_every=3)
    assert reference_task(out_only, [0], 2)["cached"] == [0]  # outputs and frame count change no frame
    for p in cache_folder().glob("*.png"):  # a truncated entry is drawn again
        p.write_bytes(p.read_bytes()[:20])
    assert reference_task(scene, [0], 2)["drawn"] == [0]
    assert not list(cache_folder().glob("*.tmp*")) and not list(cache_folder().glob(".*"))


def test_the_cache_key_follows_the_bytes_of_named_files(write_scene, tmp_path):
    import dataclasses

    from crowd.reference_cache import frame_key, scene_digest

    scene = load_scene(write_scene(TILED_SCENE))
    asset = tmp_path / "walker.glb"
    asset.write_bytes(b"one")
    ch = dataclasses.replace(scene.characters[0], file=asset)
    named = dataclasses.replace(scene, characters=(ch,))
    d1 = scene_digest(named)
    asset.write_bytes(b"two")
    assert scene_digest(named) != d1
    assert len({frame_key(scene, k, f) for k in (2, 4) for f in (0, 1)}) == 4


def test_report_refuses_bad_reference_samples_and_a_reference_that_does_not_fit(write_scene, tmp_path):
    import os

    from crowd_testutil import run_cli

    scene = write_scene(TILED_SCENE)
    out = tmp_path / "rep"
    for bad in ("9", "1", "x"):
        r = run_cli("report", scene, "--reference-samples", bad, "--out", out, "--cluster", "none")
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1 and "--reference-samples" in lines[0] and "2 to 8" in lines[0]
        assert "Traceback" not in r.stderr and not out.exists()
    env = dict(os.environ, CROWD_MEMORY_LIMIT=str(500 << 20))  # the scene fits; a K = 8 reference does not
    import subprocess
    import sys

    from crowd_testutil import REPO

    env["PYTHONPATH"] = str(REPO)
    r = subprocess.run([sys.executable, "-m", "crowd", "report", str(scene), "--reference-samples", "8", "--size",
                        "1280x720", "--out", str(out), "--cluster", "none"], capture_output=True, text=True, env=env, cwd=REPO, timeout=300)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert "--reference-samples 8: the reference at 1280x720 needs" in lines[0] and "would fit" in lines[0]
    assert not out.exists() and not list(tmp_path.glob(".rep*"))
