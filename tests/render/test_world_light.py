"""The world lit by the scene's light (render/world/draw.py, shaders/world/world_light.glsl): the light's direction and colour
shade the ground and the props; props cast into the shadow map and the ground and props receive it; the world's
statics get no blob shadow."""
import numpy as np
import pytest
from image_checks import box_faces

from lod.drawlist import DrawList
from lod.props.chain import PropChainRep, bounding_sphere
from lod.props.select import WorldSelector
from lod.props.solids import GroundRep
from lod.view import Camera
from render.world.light import make_light
from render.renderer import Renderer

SIZE = (160, 120)
BG = (0.0, 0.0, 0.0)


def box_prop(key="props:box", lo=(-0.5, 0.0, -0.5), hi=(0.5, 1.0, 0.5), rgb=(0.8, 0.8, 0.8)) -> PropChainRep:
    """An axis-aligned box as a one-level prop chain (flat normals, 4 vertices per face)."""
    pos, nrm, idx = box_faces(lo, hi)
    pos = np.asarray(pos, np.float32)
    colors = np.ones((len(pos), 4), np.float32)
    colors[:, :3] = rgb
    return PropChainRep(key=key, positions=pos, normals=np.asarray(nrm, np.float32), colors=colors,
                        indices=np.asarray(idx, np.uint32), level_first=np.zeros(1, np.int64),
                        level_count=np.array([len(idx)], np.int64), level_error=np.zeros(1),
                        sphere=bounding_sphere(pos))


def placed(*xyz):
    """(k, 3, 4) model rows of unrotated, unscaled instances at world points ``xyz``."""
    rows = np.zeros((len(xyz), 3, 4))
    rows[:, :, :3] = np.eye(3)
    rows[:, :, 3] = xyz
    return rows


def frame(r, sel, cam) -> np.ndarray:
    batches, _ = sel.select(cam, SIZE, full_detail=True)
    dl = DrawList(origin=cam.position, view=cam.view_matrix().astype(np.float32),
                  proj=cam.projection(SIZE[0] / SIZE[1]).astype(np.float32), size=SIZE, batches=batches)
    r.draw(dl, BG)
    return r.read_pixels().astype(np.float64)


def at(img, cam, points) -> np.ndarray:
    uv = cam.project(np.asarray(points, np.float64), SIZE)
    assert ((uv >= 0) & (uv < SIZE)).all(), "test points must be in view"
    return np.array([img[int(v), int(u)] for u, v in uv])


def test_light_direction_and_colour_shade_the_ground_and_props(gl_ctx):
    """The box's +x face seen by the camera: bright with the light towards +x, ambient only with the light towards
    -x (same height: the top face and the ground are alike in both); a reddish light makes the ground red."""
    cam = Camera.look_at((4.0, 5.0, 6.0), (0.0, 0.5, 0.0), fov_y=40.0)
    face = [(0.5, y, z) for y in (0.3, 0.6) for z in (-0.2, 0.2)]
    top = [(x, 1.0, z) for x in (-0.2, 0.2) for z in (-0.2, 0.2)]
    floor = [(1.7, 0.0, 1.6), (-1.6, 0.0, 2.4), (2.6, 0.0, -1.4)]
    sel = WorldSelector([(box_prop(), placed((0.0, 0.0, 0.0)))], GroundRep())
    img = {}
    with Renderer(SIZE, ctx=gl_ctx) as r:
        for rep in sel.reps:
            r.upload(rep)
        for name, light in {"east": make_light((1.0, 0.3, 0.0)), "west": make_light((-1.0, 0.3, 0.0)),
                            "red": make_light((1.0, 0.3, 0.0), color=(1.0, 0.3, 0.3))}.items():
            r.lighting.configure(light=light, mode="none")
            img[name] = frame(r, sel, cam)
    lum = {k: v.mean(axis=-1) for k, v in img.items()}
    assert (at(lum["east"], cam, face) > at(lum["west"], cam, face) + 80).all()
    assert np.abs(at(lum["east"], cam, top) - at(lum["west"], cam, top)).max() <= 2
    assert np.abs(at(lum["east"], cam, floor) - at(lum["west"], cam, floor)).max() <= 2
    red, white = at(img["red"], cam, floor), at(img["east"], cam, floor)
    assert (red[:, 0] > red[:, 2] + 10).all() and (np.abs(white[:, 0] - white[:, 2]) <= 4).all()
    assert (np.abs(red[:, 0] - white[:, 0]) <= 2).all()  # the red channel of the light is the white light's


def test_props_cast_into_the_shadow_map_and_the_ground_receives(gl_ctx):
    """A 1 m box prop on the world ground, the light 45 degrees from the zenith towards +x: the ground beside it
    on -x (the side away from the light) darkens in mode "map", the +x side and the far ground do not; a second box
    in the shadow of a tall one is darker on its lit-facing top; the world gets no blob in mode "blob"."""
    cam = Camera.look_at((0.0, 14.0, 0.01), (0.0, 0.0, 0.0), fov_y=35.0)
    sel = WorldSelector([(box_prop(), placed((0.0, 0.0, 0.0), (0.0, 0.0, -3.0))),
                         (box_prop("props:wall", (-0.25, 0.0, -0.5), (0.25, 3.0, 0.5)), placed((1.25, 0.0, -3.0)))],
                        GroundRep())
    img = {}
    with Renderer(SIZE, ctx=gl_ctx) as r:
        for rep in sel.reps:
            r.upload(rep)
        for mode in ("none", "map", "blob"):
            r.lighting.configure(light=make_light((1.0, 1.0, 0.0)), mode=mode, map_size=512)
            img[mode] = frame(r, sel, cam).mean(axis=-1)
            if mode == "map":
                assert r.lighting.last_counts["casters"] == 3  # the three prop instances, not the ground
            if mode == "blob":
                assert r.lighting.last_counts["blobs"] == 0  # blobs are the agents'
    shadow = [(x, 0.0, z) for x in (-0.8, -1.2) for z in (-0.3, 0.25)] + [(-1.35, 0.0, 0.4)]
    lit = [(x, 0.0, z) for x in (0.8, 1.2) for z in (-0.3, 0.25)] + [(-3.0, 0.0, 2.5), (-1.2, 0.0, 2.3)]
    dark, plain = at(img["map"], cam, shadow), at(img["none"], cam, shadow)
    assert (dark < 0.75 * plain).all(), (dark, plain)
    assert np.abs(at(img["map"], cam, lit) - at(img["none"], cam, lit)).max() <= 2
    # the second box's top (y 1) lies in the 3 m wall's shadow (the wall's -x face at x 1, light at 45 degrees:
    # its shadow at y 1 reaches x -1): it receives
    top = [(x, 1.0, z) for x in (-0.2, 0.2) for z in (-3.2, -2.8)]
    assert (at(img["map"], cam, top) < 0.75 * at(img["none"], cam, top)).all()
    assert np.abs(img["blob"] - img["none"]).max() <= 1  # no prop, no ground blob


@pytest.mark.parametrize("offset", [0.0, 1e6])
def test_prop_shadow_far_from_the_origin(gl_ctx, offset):
    """The same box and shadow 1e6 m from the origin (camera-relative positions in the map too)."""
    o = np.array([offset, 0.0, -offset])
    cam = Camera.look_at(o + (0.0, 14.0, 0.01), o, fov_y=35.0)
    sel = WorldSelector([(box_prop(), placed(o))], GroundRep())
    with Renderer(SIZE, ctx=gl_ctx) as r:
        for rep in sel.reps:
            r.upload(rep)
        out = {}
        for mode in ("none", "map"):
            r.lighting.configure(light=make_light((1.0, 1.0, 0.0)), mode=mode, map_size=512)
            out[mode] = frame(r, sel, cam).mean(axis=-1)
    assert np.isfinite(out["map"]).all()
    shadow = [o + (x, 0.0, z) for x in (-0.8, -1.2) for z in (-0.3, 0.25)]
    lit = [o + (x, 0.0, z) for x in (0.8, 1.2) for z in (-0.3, 0.25)]
    assert (at(out["map"], cam, shadow) < 0.75 * at(out["none"], cam, shadow)).all()
    assert np.abs(at(out["map"], cam, lit) - at(out["none"], cam, lit)).max() <= 2
