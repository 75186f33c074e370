"""The packed vertex format (render/vertex_format.py, off by default): the image stays within 45 dB of the
unpacked one, and the geomorph tables hold what the packed attributes give the vertex shader."""
import numpy as np

from lod.full.mode import NoLodSelector
from lod.full.reps import build_rep
from lod.view import Camera
from render.renderer import Renderer
from render.vertex_format import drawn, skin_attributes, surface_attributes
from sim.procedural import humanoid
from sim.state import CrowdState


def test_packed_vertices_keep_the_image(gl_ctx):
    rep = build_rep(humanoid(3000, seed=8), key="vf:h")
    st = CrowdState.empty(8)
    st.position[:, 0] = np.arange(8) * 0.8 - 2.8
    st.heading[:] = np.linspace(0, 6, 8)
    st.anim_time[:] = 0.11 * np.arange(8)
    cam = Camera.look_at((0.0, 1.8, 4.5), (0.0, 0.9, 0.0), fov_y=50.0, near=0.1, far=50.0)
    size = (256, 160)
    images = []
    for packed in (True, False):
        with Renderer(size, ctx=gl_ctx, debug=True) as r:
            r.packed_vertices = packed
            r.upload(rep)
            r.draw(NoLodSelector([rep]).select(st, cam, size))
            images.append(r.read_pixels().astype(np.int64))
    a, b = images
    assert np.any(a != a[0, 0])
    mse = np.mean((a - b) ** 2.0)
    assert mse == 0 or 10 * np.log10(255.0 ** 2 / mse) >= 45.0
    assert (np.abs(a - b).max(axis=2) > 2).mean() <= 5e-3


def test_formats_and_drawn_values():
    rep = build_rep(humanoid(800, seed=2), key="vf:f")
    made = {}

    def buf(a, label):
        made[label] = np.ascontiguousarray(a)
        return label

    fmts = {name: fmt for _, fmt, name in surface_attributes(rep, buf, True) + skin_attributes(rep, buf, True)}
    assert fmts == {"in_position": "3f", "in_normal": "3f2", "in_color": "4f2", "in_joints": "4u1",
                    "in_weights": "4f2"}
    assert made["normals"].dtype == np.float16 and made["positions"].dtype == np.float32
    # the geomorph tables' values are the packed attributes as the shader reads them (exact float16 -> float32)
    assert np.array_equal(drawn(rep.weights, 4, True), made["weights"].astype(np.float32))
    assert np.array_equal(drawn(rep.colors, 4, False), np.asarray(rep.colors, np.float32))
    assert np.abs(drawn(rep.normals, 3, True) - rep.normals).max() < 1e-3
