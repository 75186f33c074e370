"""Blob shadows of many agents (render/world/blobs.py): the numba rows equal render.world.shadows.blob_instances (the numpy
reference), and drawing only the quads that can cover a pixel centre leaves the image unchanged while dropping
most of a far crowd's blobs."""
import numpy as np

import render.world.shadows as shadows
from lod.drawlist import DrawBatch, DrawList
from lod.view import Camera
from render.world import blobs as rb
from render.renderer import Renderer
from render.world.shadows import blob_instances, footprint
from test_shadows import box_rep, ground_rep


def _batches(rng, n=3000):
    out = []
    for k, dt in ((n, np.float32), (n // 3, np.float64), (5, np.float32)):
        yaw, s = rng.uniform(0, 6.3, k), rng.uniform(0.5, 2.0, k)
        d = np.zeros((k, 16), dt)
        d[:, 0], d[:, 2], d[:, 5], d[:, 8], d[:, 10] = np.cos(yaw) * s, np.sin(yaw) * s, s, -np.sin(yaw) * s, \
            np.cos(yaw) * s
        d[:, [3, 7, 11]] = rng.uniform(-3000, 3000, (k, 3))
        ids = rng.integers(-2, n, k).astype(np.int32)  # statics (< 0) and agents in two batches
        out.append(DrawBatch("x", 0, ids, d))
    out[0].instance_data[7, 3] = np.nan  # a non-finite first row: that agent gets no blob at all
    out.append(DrawBatch("y", 0, np.arange(4, dtype=np.int32), out[0].instance_data[:4]))  # no footprint
    return out


def test_blob_rows_equal_the_reference():
    rng = np.random.default_rng(1)
    fp = footprint(box_rep("x", (-0.3, 0.1, -0.2), (0.25, 1.8, 0.3)))
    bs = _batches(rng)
    ref = blob_instances(bs, {"x": fp})
    got = rb.blob_rows(bs, {"x": fp})
    assert got.dtype == np.float32 and ref.shape[0] > 1000
    np.testing.assert_array_equal(got, ref)
    assert rb.blob_rows([], {}).shape == (0, 4)


def test_only_covering_blobs_are_drawn_and_the_image_is_the_same(gl_ctx, monkeypatch):
    """A crowd on a ground seen from far and high (sub-pixel blobs) and a few near agents: the frame drawn
    with every blob and the one drawn with the covering blobs only are the same pixels; most far blobs are
    dropped; near ones and those behind the camera plane are kept."""
    size = (200, 150)
    cam = Camera.look_at((0.0, 150.0, 260.0), (0.0, 0.0, -100.0), fov_y=40.0, near=0.5, far=5000.0)
    rng = np.random.default_rng(2)
    far = np.column_stack([rng.uniform(-300, 300, 6000), np.zeros(6000), rng.uniform(-600, 100, 6000)])
    near = np.array([[0.0, 0.0, 240.0], [1.0, 0.0, 245.0], [0.0, 0.0, 300.0]])  # the last is behind the camera
    feet = np.concatenate([far, near])
    agent = box_rep("static:agent", (-0.3, 0.0, -0.3), (0.3, 1.7, 0.3))
    ground = ground_rep(2000.0)
    images, counts = [], []
    with Renderer(size, ctx=gl_ctx) as r:
        # the hardware path only: the blobs are drawn among the plug-in drawers, after the hardware batches and
        # before the compute rasteriser's copies (render/raster/), so they darken the feet of hardware-drawn agents
        # only; what this test counts is the blob pass itself
        r.compute_raster = False
        r.upload(ground)
        r.upload(agent)
        r.lighting.configure(mode="blob")

        def frame():
            d = np.zeros((feet.shape[0], 16), np.float32)
            d[:, 0] = d[:, 5] = d[:, 10] = 1.0
            d[:, [3, 7, 11]] = feet - cam.position
            g = np.zeros((1, 16), np.float32)
            g[0, 0] = g[0, 5] = g[0, 10] = 1.0
            g[0, [3, 7, 11]] = -cam.position
            dl = DrawList(origin=cam.position.copy(), view=cam.view_matrix().astype(np.float32),
                          proj=cam.projection(size[0] / size[1]).astype(np.float32), size=size,
                          batches=[DrawBatch("static:ground", 0, np.array([-1], np.int32), g),
                                   DrawBatch("static:agent", 0, np.arange(feet.shape[0], dtype=np.int32), d)])
            r.draw(dl)
            images.append(r.read_pixels())
            counts.append(dict(r.lighting.last_counts))

        frame()
        monkeypatch.setattr(shadows, "covering", lambda b, *a, **k: np.ones(b.shape[0], bool))
        frame()
        r.lighting.configure(mode="none")
        frame()
    assert counts[0]["blobs"] == counts[1]["blobs"] == feet.shape[0]
    assert counts[1]["blobs_drawn"] == feet.shape[0]
    assert 3 <= counts[0]["blobs_drawn"] < feet.shape[0] // 2, counts[0]
    np.testing.assert_array_equal(images[0], images[1])
    assert (images[0] != images[2]).any(axis=-1).sum() > 100  # the blobs do show


def test_covering_keeps_near_clipped_and_pixel_centre_quads():
    """Window x = 5 x + 5, y = 5 z + 5 on a 10 x 10 viewport (pixel centres at k + 0.5)."""
    vp = np.zeros((4, 4))
    vp[0, 0] = vp[1, 2] = vp[3, 3] = 1.0
    size = (10, 10)
    b = np.array([[0.0, 0.0, 0.0, 0.001],    # at window (5, 5): a pixel corner, no centre
                  [0.01, 0.0, 0.01, 0.001],  # (5.05, 5.05): within the margin of no centre either
                  [0.1, 0.0, 0.0, 0.001],    # (5.5, 5.0): on a centre column, between rows
                  [0.1, 0.0, 0.1, 0.001],    # (5.5, 5.5): on a pixel centre
                  [5.0, 0.0, 5.0, 0.5],      # outside the viewport
                  [0.0, 0.0, 0.0, 0.3],      # covers several centres
                  [0.19, 0.0, 0.19, 0.1]], np.float32)  # (5.95, 5.95) +- 0.5: (5.5, 5.5) in its corner, off the disc
    assert rb.covering(b, vp, size, lift=0.0).tolist() == [False, False, False, True, False, True, False]
    assert rb.covering(b[-1:], vp, size, lift=0.0, margin=0.2).tolist() == [True]  # within a wider margin
    vp[3] = [0.0, 0.0, 1.0, 0.0]  # w = z: a quad reaching behind the camera plane is kept
    assert rb.covering(np.array([[0.0, 0.0, 0.0, 0.5]], np.float32), vp, size, 0.0).tolist() == [True]
