"""Back-face culling of single-sided reps (``Mesh.double_sided`` False; render.renderer): it culls what
faces away, and on the closed procedural characters it draws the same image as drawing both sides."""
import dataclasses

import numpy as np
import pytest

from lod.full.mode import NoLodSelector
from lod.full.reps import build_rep
from lod.view import Camera
from render.renderer import Renderer
from sim.mesh import Mesh
from sim.procedural import humanoid, quadruped
from sim.state import CrowdState


def _crowd(n, spacing):
    st = CrowdState.empty(n)
    k = int(np.ceil(np.sqrt(n)))
    i = np.arange(n)
    st.position[:, 0] = (i % k - (k - 1) / 2) * spacing
    st.position[:, 2] = (i // k - (k - 1) / 2) * spacing
    st.heading[:] = np.linspace(-np.pi, np.pi, n, endpoint=False)
    st.anim_time[:] = 0.13 * np.arange(n)  # every instance its own pose
    return st


def _draw(ctx, rep, st, cam, size):
    with Renderer(size, ctx=ctx, debug=True) as r:
        r.upload(rep)
        r.draw(NoLodSelector([rep]).select(st, cam, size))
        return r.read_pixels().copy(), r.last_timings["samples_passed"]


@pytest.mark.parametrize("make", [humanoid, quadruped])
def test_procedural_characters_are_closed_and_wound_outwards(make):
    """Every triangle's signed volume sums positive per character (counter-clockwise seen from outside) and
    the characters are marked single-sided."""
    m = make(2000, seed=1).mesh
    assert m.double_sided is False
    p = np.asarray(m.positions, np.float64)[np.asarray(m.indices).reshape(-1, 3)]
    vol = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0
    assert vol > 0.0


@pytest.mark.parametrize("make", [humanoid, quadruped])
def test_culling_a_closed_character_keeps_the_image(gl_ctx, make):
    """A crowd of closed characters drawn single-sided (back faces culled) and double-sided: at most
    0.05 % of the pixels differ (back faces seen through sub-pixel gaps where parts meet) and the
    image is >= 45 dB PSNR of the two-sided one."""
    ch = make(3000, seed=2)
    one = build_rep(ch, key="cull:one")
    both = dataclasses.replace(one, key="cull:both", double_sided=True)
    assert one.double_sided is False
    st = _crowd(16, 1.6)
    cam = Camera.look_at((0.0, 3.5, 7.5), (0.0, 0.8, 0.0), fov_y=50.0, near=0.1, far=100.0)
    size = (320, 180)
    a, sa = _draw(gl_ctx, one, st, cam, size)
    b, sb = _draw(gl_ctx, both, st, cam, size)
    assert b.std() > 0
    diff = np.any(a != b, axis=2)
    assert diff.mean() <= 5e-4, diff.sum()
    mse = np.mean((a.astype(np.float64) - b) ** 2)
    assert mse == 0 or 10 * np.log10(255.0 ** 2 / mse) >= 45.0
    assert sa <= sb  # culled fragments never pass


def test_single_sided_rep_culls_faces_turned_away(gl_ctx):
    """One triangle wound clockwise as the camera sees it: drawn when double-sided, culled when not;
    turned around (counter-clockwise) it is drawn either way."""
    p = np.array([[-1, 0, 0], [0, 1.5, 0], [1, 0, 0]], np.float32)  # clockwise seen from +Z
    for tri, shown_single in (([0, 1, 2], False), ([0, 2, 1], True)):
        mesh = Mesh(positions=p, indices=np.array([tri], np.uint32))
        st = _crowd(1, 1.0)
        st.heading[:] = 0.0
        cam = Camera.look_at((0.0, 0.7, 4.0), (0.0, 0.7, 0.0), fov_y=50.0, near=0.1, far=100.0)
        size = (64, 48)
        for double in (True, False):
            rep = build_rep(dataclasses.replace(mesh, double_sided=double), key="cull:tri")
            im, samples = _draw(gl_ctx, rep, st, cam, size)
            drawn = samples > 0
            assert drawn == (double or shown_single), (tri, double)
            assert bool(np.any(im != im[0, 0])) == drawn  # pixels other than the background
