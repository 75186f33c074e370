"""The light and the shadows (render/world/light.py, render/world/shadows.py): blob shadows under each agent's feet, a shadow
map that darkens the ground where a known occluder's shadow falls and not elsewhere, light validation."""
import math

import numpy as np
import pytest
from image_checks import box_faces

from lod.drawlist import DrawBatch, DrawList
from lod.full.reps import StaticRep
from lod.view import Camera
from render.world.light import Light, LightError, make_light
from render.renderer import Renderer
from render.world.shadows import (BLOB_HEIGHT_RANGE, blob_instances, fit_light_matrix, footprint, light_basis)

SIZE = (160, 120)
GROUND = (0.5, 0.5, 0.5)


def _rep(key, positions, normals, indices, color) -> StaticRep:
    p = np.asarray(positions, np.float32)
    col = np.tile(np.asarray([*color, 1.0], np.float32), (p.shape[0], 1))
    return StaticRep(key, p, np.asarray(normals, np.float32), col, np.asarray(indices, np.uint32).reshape(-1, 3),
                     np.stack([p.min(0), p.max(0)]), np.array([0.0, 0.0, 0.0, float(np.abs(p).max()) * 2]))


def box_rep(key, lo, hi, color=(0.8, 0.2, 0.2)) -> StaticRep:
    """An axis-aligned box, 4 vertices per face (flat normals)."""
    pos, nrm, tris = box_faces(lo, hi)
    idx = [c for t in tris for c in t]
    return _rep(key, pos, nrm, idx, color)


def ground_rep(half=20.0) -> StaticRep:
    pos = [(-half, 0, -half), (half, 0, -half), (half, 0, half), (-half, 0, half)]
    return _rep("static:ground", pos, [(0, 1, 0)] * 4, [0, 1, 2, 0, 2, 3], GROUND)


def drawlist(camera, batches) -> DrawList:
    """Batches given as (rep key, ids, world (k, 3) translations) made camera-relative."""
    out = []
    for key, ids, tr in batches:
        tr = np.asarray(tr, np.float64).reshape(-1, 3)
        d = np.zeros((tr.shape[0], 16), np.float32)
        d[:, 0] = d[:, 5] = d[:, 10] = 1.0
        d[:, [3, 7, 11]] = tr - camera.position
        out.append(DrawBatch(key, 0, np.asarray(ids, np.int32), d))
    return DrawList(origin=camera.position.copy(), view=camera.view_matrix().astype(np.float32),
                    proj=camera.projection(SIZE[0] / SIZE[1]).astype(np.float32), size=SIZE, batches=out)


def luma(px) -> np.ndarray:
    return np.asarray(px, np.float64).mean(axis=-1)


def at(img, camera, points) -> np.ndarray:
    """Pixel values of ``img`` at the projections of world ``points``."""
    uv = camera.project(np.asarray(points, np.float64), SIZE)
    return np.array([img[int(v), int(u)] for u, v in uv])


# ---------------------------------------------------------------------------------------------------------- light
def test_make_light_normalises_and_refuses_degenerate_directions():
    light = make_light([0.0, 2.0, 0.0], [1.0, 0.9, 0.8], 0.25)
    assert light.direction == (0.0, 1.0, 0.0) and light.ambient == 0.25
    for bad in ([0.0, 0.0, 0.0], [1e-9, 0.0, 0.0], [math.nan, 1.0, 0.0], [math.inf, 0.0, 0.0], [1.0, 2.0], "up"):
        with pytest.raises(LightError) as e:
            make_light(bad)
        assert e.value.key == "light_dir" and "\n" not in str(e.value)
    with pytest.raises(LightError, match="light_color"):
        make_light(light_dir := (0, 1, 0), color=(-1.0, 0.0, 0.0))
    with pytest.raises(LightError, match="ambient"):
        make_light(light_dir, ambient=math.nan)
    d = Light().direction
    assert abs(sum(x * x for x in d) - 1.0) < 1e-12


def test_light_direction_and_colour_shade_the_characters(gl_ctx):
    """A quad facing up: brighter lit from above than from the side; a black light leaves ambient + headlight."""
    cam = Camera.look_at((0.0, 10.0, 0.01), (0.0, 0.0, 0.0), fov_y=40.0)
    centre = [(0.0, 0.0, 0.0)]
    values = {}
    with Renderer(SIZE, ctx=gl_ctx) as r:
        r.upload(ground_rep())
        for name, light in {"above": Light(direction=(0.0, 1.0, 0.0)), "side": Light(direction=(1.0, 0.0, 0.0)),
                            "black": Light(direction=(0.0, 1.0, 0.0), color=(0.0, 0.0, 0.0))}.items():
            r.lighting.configure(light=light, mode="none")
            r.draw(drawlist(cam, [("static:ground", [-1], centre)]), background=(0, 0, 0))
            values[name] = luma(at(r.read_pixels(), cam, centre))[0]
    assert values["above"] > values["side"] + 20
    assert values["black"] == pytest.approx(values["side"], abs=2)  # light at 90 degrees: no direct term either


# ---------------------------------------------------------------------------------------------------------- blobs
def test_footprint_of_a_box_and_blob_instances_dedupe_and_skip_statics():
    fp = footprint(box_rep("x", (-0.1, 0.0, -0.1), (0.1, 1.7, 0.1)))
    assert fp[:3] == pytest.approx((0.0, 0.0, 0.0))
    assert fp[3] == pytest.approx(BLOB_HEIGHT_RANGE[0] * 1.7)  # a thin agent: the radius floor
    d = np.zeros((2, 16), np.float32)
    d[:, 0] = d[:, 5] = d[:, 10] = 2.0  # scale 2
    d[:, [3, 7, 11]] = [[1.0, 0.5, 2.0], [np.nan, 0.0, 0.0]]
    b1 = DrawBatch("x", 0, np.array([7, 8], np.int32), d)
    b2 = DrawBatch("x", 0, np.array([7], np.int32), d[:1])  # the same agent again (a screen-door transition)
    st = DrawBatch("x", 0, np.array([-1], np.int32), d[:1])  # a static
    out = blob_instances([b1, b2, st], {"x": fp})
    assert out.shape == (1, 4) and np.isfinite(out).all()  # the NaN row is dropped, agent 7 once
    assert out[0] == pytest.approx([1.0, 0.5, 2.0, 2 * fp[3]])
    assert blob_instances([], {}).shape == (0, 4)


def test_blob_shadow_lies_under_each_agents_feet(gl_ctx):
    """Agents seen from above on a plain ground: darker pixels around each agent's feet (beside its thin body),
    the ground's own colour half-way between agents and far from them, and no darkening with shadows = none."""
    cam = Camera.look_at((0.0, 12.0, 0.01), (0.0, 0.0, 0.0), fov_y=45.0)
    feet = np.array([[-3.0, 0.0, 0.0], [0.0, 0.0, 2.0], [3.0, 0.0, -1.0], [2.0, 0.0, 3.0]])
    agent = box_rep("static:agent", (-0.05, 0.0, -0.05), (0.05, 1.7, 0.05))
    r_blob = footprint(agent)[3]
    images = {}
    with Renderer(SIZE, ctx=gl_ctx) as r:
        r.upload(ground_rep())
        r.upload(agent)
        for mode in ("none", "blob"):
            r.lighting.configure(mode=mode)
            r.draw(drawlist(cam, [("static:ground", [-1], [(0, 0, 0)]), ("static:agent", range(4), feet)]))
            images[mode] = luma(r.read_pixels())
        assert r.lighting.last_counts["blobs"] == 4
    # beside the feet, across the view direction of the lean (bodies lean away from the image centre)
    ring = []
    for f in feet:
        side = np.array([-f[2], 0.0, f[0]]) / np.hypot(f[0], f[2])
        ring += [f + 0.5 * r_blob * side, f - 0.5 * r_blob * side]
    ground = images["none"]
    dark, lit = at(images["blob"], cam, ring), at(ground, cam, ring)
    assert (dark < lit - 15).all(), (dark, lit)
    far = [(-5.0, 0.0, 4.0), (5.0, 0.0, 4.5), (0.0, 0.0, -3.5), (-1.5, 0.0, 1.0)]  # > 1 m from every agent
    assert np.abs(at(images["blob"], cam, far) - at(ground, cam, far)).max() <= 1
    # outside the discs the two images are the same pixels
    uv = cam.project(feet, SIZE)
    yy, xx = np.mgrid[0:SIZE[1], 0:SIZE[0]]
    px_per_m = np.linalg.norm(cam.project([[1.0, 0, 0]], SIZE) - cam.project([[0.0, 0, 0]], SIZE))
    near = np.zeros(SIZE[::-1], bool)
    for u, v in uv:
        near |= np.hypot(xx + 0.5 - u, yy + 0.5 - v) <= (r_blob + 1.9) * px_per_m  # disc + the body's lean
    assert np.abs(images["blob"] - ground)[~near].max() <= 1


def test_blob_shadows_survive_ground_drawn_by_the_compute_rasteriser(gl_ctx):
    """Ground of small triangles taken by the compute rasteriser: it composes before the blob shadows (decals
    that write no depth), so the blobs stay, and the frame is the hardware path's."""
    cam = Camera.look_at((0.0, 12.0, 0.01), (0.0, 0.0, 0.0), fov_y=45.0)
    feet = np.array([[-3.0, 0.0, 0.0], [0.0, 0.0, 2.0], [3.0, 0.0, -1.0], [2.0, 0.0, 3.0]])
    agent = box_rep("static:agent", (-0.05, 0.0, -0.05), (0.05, 1.7, 0.05))
    n, half = 60, 12.0  # 7,200 triangles of ~0.4 m: 2-3 pixels each
    g = np.linspace(-half, half, n + 1)
    xx, zz = np.meshgrid(g, g)
    pos = np.stack([xx.ravel(), np.zeros(xx.size), zz.ravel()], 1)
    q = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    tris = np.stack([q, q + n + 1, q + 1, q + 1, q + n + 1, q + n + 2], 1).reshape(-1, 3)
    ground = _rep("static:ground", pos, np.tile([0.0, 1.0, 0.0], (pos.shape[0], 1)), tris.ravel(), GROUND)
    images, raster = {}, {}
    with Renderer(SIZE, ctx=gl_ctx) as r:
        r.upload(ground)
        r.upload(agent)
        r.lighting.configure(mode="blob")
        for route in ("hardware", "compute"):
            r.compute_raster = route == "compute"
            r.raster.route_all = route == "compute"
            dl = drawlist(cam, [("static:ground", [-1], [(0, 0, 0)]), ("static:agent", range(4), feet)])
            r.draw(dl)
            images[route], raster[route] = luma(r.read_pixels()), dl.stats["raster_triangles"]
        r.raster.route_all = False
    assert raster["hardware"] == 0 and raster["compute"] > 5000
    r_blob = footprint(agent)[3]
    ring = [f + 0.5 * r_blob * np.array([-f[2], 0.0, f[0]]) / np.hypot(f[0], f[2]) for f in feet]
    assert (at(images["compute"], cam, ring) < at(images["compute"], cam, [(-5.0, 0.0, 4.0)])[0] - 15).all()
    assert np.abs(images["compute"] - images["hardware"]).mean() < 0.5


# ---------------------------------------------------------------------------------------------------------- map
def test_fit_light_matrix_holds_the_spheres_and_refuses_nothing_finite():
    c = np.array([[0.0, 0.0, 0.0], [10.0, 2.0, -5.0], [-3.0, 1.0, 4.0]])
    r = np.array([1.0, 2.0, 0.5])
    L = (0.3, 0.8, 0.2)
    P = fit_light_matrix(L, c, r, 1024, origin=(1e6, 0.0, -2e6))  # far from the origin: still finite
    R = light_basis(L)
    assert np.allclose(R @ R.T, np.eye(3)) and np.allclose(R[2], np.asarray(L) / np.linalg.norm(L))
    for ci, ri in zip(c, r):
        for s in (-1, 1):
            for axis in range(3):
                p = ci + s * ri * R[axis]
                q = P @ np.append(p, 1.0)
                assert (np.abs(q[:3]) <= 1.0 + 1e-9).all()
    coincident = fit_light_matrix((0.0, 1.0, 0.0), np.ones((5, 3)), np.zeros(5), 1024)  # degenerate: still finite
    assert coincident is not None and np.isfinite(coincident).all()
    assert fit_light_matrix(L, np.zeros((0, 3)), np.zeros(0), 1024) is None
    assert fit_light_matrix(L, [[np.nan, 0, 0]], [1.0], 1024) is None


@pytest.mark.parametrize("casts", ["box"])
def test_shadow_map_darkens_the_ground_where_the_occluders_shadow_falls(gl_ctx, casts):
    """A 1 m box on the ground, the light 45 degrees from the zenith towards +x: the shadow lies on -x beside the
    box (x in (-1.5, -0.5)) and nothing darkens the +x side; with shadows = none both sides are alike."""
    cam = Camera.look_at((0.0, 14.0, 0.01), (0.0, 0.0, 0.0), fov_y=35.0)
    box = box_rep("static:box", (-0.5, 0.0, -0.5), (0.5, 1.0, 0.5))
    images = {}
    with Renderer(SIZE, ctx=gl_ctx) as r:
        r.upload(ground_rep())
        r.upload(box)
        for mode in ("none", "map"):
            r.lighting.configure(light=make_light((1.0, 1.0, 0.0)), mode=mode, map_size=512)
            r.draw(drawlist(cam, [("static:ground", [-1], [(0, 0, 0)]), ("static:box", [-1], [(0, 0, 0)])]))
            images[mode] = luma(r.read_pixels())
        assert r.lighting.last_counts["casters"] == 1
    shadow = [(-1.0, 0.0, z) for z in (-0.3, 0.0, 0.3)] + [(-1.3, 0.0, 0.0), (-0.75, 0.0, 0.2)]
    lit = [(1.0, 0.0, z) for z in (-0.3, 0.0, 0.3)] + [(3.0, 0.0, 2.0), (-3.0, 0.0, 2.5), (-1.0, 0.0, -2.0)]
    dark, plain = at(images["map"], cam, shadow), at(images["none"], cam, shadow)
    assert (dark < 0.75 * plain).all(), (dark, plain)  # the direct term (0.55 cos 45) is gone there
    assert np.abs(at(images["map"], cam, lit) - at(images["none"], cam, lit)).max() <= 2
    # mirror symmetry without shadows: the two sides of the box are alike
    assert np.abs(at(images["none"], cam, shadow[:3]) - at(images["none"], cam, lit[:3])).max() <= 2


def test_lit_programs_compile_the_map_lookup_only_with_shadow_maps(gl_ctx):
    """llvmpipe runs a uniform branch both ways, so a renderer without shadow maps compiles no lookup (the
    ground's pixels cost half as much); switching to mode "map" after the upload re-uploads what was drawn,
    its programs with the lookup, and back (render.renderer.Renderer.reprogram)."""
    box = box_rep("static:box", (-0.5, 0.0, -0.5), (0.5, 1.0, 0.5))
    with Renderer(SIZE, ctx=gl_ctx) as r:
        r.upload(ground_rep())
        r.upload(box)
        assert r.lighting.mode == "none" and "u_shadow_map" not in r._reps["static:box"].vao.program
        first = r._reps["static:box"]
        r.lighting.configure(mode="map")
        assert "u_shadow_map" in r._reps["static:box"].vao.program and r._reps["static:box"] is not first
        assert list(r._sources) == ["static:ground", "static:box"]  # re-uploaded in upload order
        kept = r._reps["static:box"]
        r.lighting.configure(mode="map", map_size=512)  # no change of the lookup: nothing re-uploaded
        assert r._reps["static:box"] is kept
        r.lighting.configure(mode="blob")
        assert "u_shadow_map" not in r._reps["static:box"].vao.program
