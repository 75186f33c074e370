"""The headlight from the pixel's camera ray (render/screen.py, ``lit.frag`` with PIXEL_RAY) instead of
the interpolated camera-relative position: the ray points where the position did, and images agree."""
import numpy as np
import pytest

from lod.full.mode import NoLodSelector
from lod.full.reps import build_rep
from lod.view import Camera
from render.screen import pixel_ray_matrix
from render.renderer import Renderer
from sim.procedural import humanoid
from sim.state import CrowdState


@pytest.mark.parametrize("size", [(1280, 720), (97, 61)])
def test_ray_through_a_pixel_points_at_what_projects_there(size):
    rng = np.random.default_rng(3)
    for _ in range(5):
        eye = rng.uniform(-50, 50, 3)
        cam = Camera.look_at(eye, eye + rng.normal(size=3), fov_y=rng.uniform(20, 90), near=0.05, far=500.0)
        vp = cam.projection(size[0] / size[1]) @ cam.view_matrix()  # camera-relative, as the renderer draws
        a = pixel_ray_matrix(vp, size)
        # points in front of the camera (camera-relative), projected to window coordinates
        fwd = -np.asarray(cam.rotation)[:, 2]
        pts = fwd * rng.uniform(0.1, 400, (50, 1)) + rng.normal(scale=3.0, size=(50, 3))
        pts = pts[(pts @ fwd) > 0.06]
        clip = np.c_[pts, np.ones(len(pts))] @ vp.T
        ndc = clip[:, :3] / clip[:, 3:]
        win = np.c_[(ndc[:, 0] + 1) * size[0] / 2, (ndc[:, 1] + 1) * size[1] / 2, np.ones(len(pts))]
        ray = win @ a.T
        cos = np.einsum("ij,ij->i", ray, pts) / np.linalg.norm(ray, axis=1) / np.linalg.norm(pts, axis=1)
        assert np.all(cos > 1 - 1e-9)


def test_headlight_from_the_pixel_ray_keeps_the_image(gl_ctx):
    """A crowd lit with the pixel ray and with the interpolated position: >= 50 dB PSNR, and at most 0.1 % of
    the pixels differ by more than one 8-bit level."""
    ch = humanoid(3000, seed=4)
    rep = build_rep(ch, key="ray:h")
    st = CrowdState.empty(9)
    i = np.arange(9)
    st.position[:, 0] = (i % 3 - 1) * 1.3
    st.position[:, 2] = (i // 3 - 1) * 1.3
    st.heading[:] = np.linspace(0, 6, 9)
    st.anim_time[:] = 0.1 * i
    cam = Camera.look_at((0.5, 2.0, 4.5), (0.0, 0.9, 0.0), fov_y=50.0, near=0.1, far=100.0)
    size = (320, 200)
    images = []
    for ray in (True, False):
        with Renderer(size, ctx=gl_ctx, debug=True) as r:
            r.pixel_ray = ray
            r.upload(rep)
            r.draw(NoLodSelector([rep]).select(st, cam, size))
            images.append(r.read_pixels().astype(np.int64))
    a, b = images
    assert np.any(a != a[0, 0])
    assert (np.abs(a - b).max(axis=2) > 1).mean() <= 1e-3
    mse = np.mean((a - b) ** 2.0)
    assert mse == 0 or 10 * np.log10(255.0 ** 2 / mse) >= 50.0
