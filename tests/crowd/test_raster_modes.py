"""The compute rasteriser of small triangles (render/raster/) in every LOD mode: a scene of characters and
props drawn with the switch on and off gives the same frame within the acceptance bound (PSNR >= 45 dB), and
the compute path takes the triangles it should (stats["raster_triangles"], frames.csv)."""
import csv

import numpy as np
import pytest
from crowd_testutil import REPO, tiny_scene

from crowd.engine import Engine
from crowd.scene import load_scene

MODES = ("none", "triangles", "points", "clusters", "auto")
W, H = 240, 160


def _psnr(a, b) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(255.0 ** 2 / mse)


def _scene(tmp_path, threshold=8.0):
    props = f"""
[[props]]
name = "planter"
file = "{REPO / 'scenes' / 'props' / 'planter.ply'}"
positions = [[-2.0, 0.0, -3.0], [3.5, 0.0, -2.0]]
"""
    text = tiny_scene(replace={"rows = 2": "rows = 3", "cols = 2": "cols = 4",
                               "png_every = 1": f"png_every = 1\nraster_threshold = {threshold}",
                               "position = [1.0, 2.0, 7.0]": "position = [1.0, 3.0, 11.0]"}, append=props)
    p = tmp_path / f"raster{threshold:g}.toml"
    p.write_text(text)
    return load_scene(p)


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("raster")
    out = {}
    # the cluster cuts' route is priced against the pose pass it needs (render.raster.hook._pose_pays): these
    # twelve small walkers would stay on the hardware path; this test compares the two paths' pixels
    with pytest.MonkeyPatch.context() as mp, Engine(_scene(tmp), overrides={"size": (W, H)}, quiet=True) as e:
        mp.setattr("render.raster.hook.POSE_PAYS_TRIANGLES", 0.0)
        r = e._open_renderer()
        e.step()
        cam = e.camera_at(e.world.time)
        for m in MODES:
            e.set_lod_mode(m)
            dl = e.select(cam, (W, H))
            for on in (True, False):
                r.compute_raster = on
                r.draw(dl, (0.1, 0.1, 0.12))
                out[m, on] = (r.read_pixels().copy(), int(dl.stats["raster_triangles"]), int(dl.stats.get("props", 0)))
            r.compute_raster = True
    return out


@pytest.mark.parametrize("mode", MODES)
def test_every_mode_draws_the_same_frame_with_the_switch_on_and_off(frames, mode):
    on, n_on, props = frames[mode, True]
    off, n_off, _ = frames[mode, False]
    assert on.std() > 5
    assert _psnr(on, off) >= 45.0
    assert n_off == 0
    if mode != "points":  # mode points draws the props at a coarse chain level: triangles beyond the threshold
        assert n_on > 0  # the props at least
    if mode in ("none", "triangles", "clusters"):
        assert n_on > props  # and characters: full detail, chain levels, cluster cuts


def test_full_detail_goes_to_compute(frames):
    """Mode none: the small characters and the props: most triangles of the frame in compute."""
    assert frames["none", True][1] > 3000


def test_frames_csv_counts_the_compute_triangles(tmp_path):
    """frames.csv has raster_triangles; threshold 0 turns the compute path off."""
    for thr, positive in ((8.0, True), (0.0, False)):
        with Engine(_scene(tmp_path, thr), overrides={"size": (W, H)}, quiet=True) as e:
            res = e.run(frames=2, out_dir=tmp_path / f"run{thr:g}")
        rows = list(csv.DictReader(open(res.out_dir / "frames.csv")))
        vals = [int(r["raster_triangles"]) for r in rows]
        tris = [int(r["triangles"]) + int(r["props"]) for r in rows]  # props: triangles of props and solids
        assert (min(vals) > 0) == positive and all(v <= t for v, t in zip(vals, tris))
