"""The world drawn: obstacle solids of each shape and props of each file format cover the pixels
the camera projects them to, in every LOD mode; the ground is drawn unless ``ground = false`` and
keeps its precision far from the origin."""
import numpy as np
import pytest
from prop_files import write_prop

from crowd.engine import Engine
from crowd.scene import load_scene
from lod.modes import MODES

BG = (0.1, 0.1, 0.12)
SIZE = (320, 180)
#: props: format -> (position, colour with one dominant channel)
PROPS = {"obj": ((3.0, -2.0), (0.9, 0.1, 0.1)), "ply": ((6.0, -2.0), (0.1, 0.9, 0.1)),
         "stl": ((-5.0, 3.0), None), "glb": ((-1.5, 3.0), (0.1, 0.1, 0.9)), "gltf": ((2.0, 3.0), (0.9, 0.9, 0.1))}
CIRCLE = ((-6.0, -2.0), 0.7, 1.5)
BOX = ((-3.0, -2.0), (1.2, 1.0), 20.0, 1.0)
POLY = ([[-0.8, -2.6], [0.8, -2.6], [0.0, -1.2]], 1.2)

SCENE = """
name = "world"
seed = 1
dt = 0.05
frames = 1

[[effects]]
name = "animation"

[[effects]]
name = "obstacles"
circles = [{{ center = [{cx}, {cz}], radius = {cr}, height = {ch} }}]
boxes = [{{ center = [{bx}, {bz}], size = [{bsx}, {bsz}], yaw = {byaw}, height = {bh} }}]
polygons = [{{ points = {poly}, height = {ph} }}]

[[characters]]
name = "walker"
generator = "humanoid"
triangles = 600

[[placement]]
kind = "list"
character = "walker"
positions = [[0.0, 0.0, 60.0]]

{props}
[camera]
position = [0.0, 7.0, 11.0]
target = [0.0, 0.3, 0.0]

[render]
size = [{w}, {h}]
background = [{bg0}, {bg1}, {bg2}]
ground = {ground}

[lod]
mode = "{mode}"
"""


def _scene(tmp, mode="none", ground=False, extra=""):
    props = ""
    for fmt, ((x, z), rgb) in PROPS.items():
        write_prop(tmp / f"box_{fmt}", fmt, size=(1.0, 1.0, 1.0), rgb=rgb or (0.5, 0.5, 0.5))
        props += f'[[props]]\nfile = "box_{fmt}.{fmt}"\npositions = [[{x}, 0.0, {z}]]\n\n'
    (cx, cz), cr, ch = CIRCLE
    (bx, bz), (bsx, bsz), byaw, bh = BOX
    text = SCENE.format(cx=cx, cz=cz, cr=cr, ch=ch, bx=bx, bz=bz, bsx=bsx, bsz=bsz, byaw=byaw, bh=bh,
                        poly=POLY[0], ph=POLY[1], props=props + extra, w=SIZE[0], h=SIZE[1], bg0=BG[0], bg1=BG[1],
                        bg2=BG[2], ground="true" if ground else "false", mode=mode)
    p = tmp / f"world_{mode}.toml"
    p.write_text(text)
    return load_scene(p)


def _frame(scene):
    with Engine(scene, quiet=True) as e:
        r = e.open_renderer()
        cam = e.camera_at(0.0)
        dl = e.select(cam, SIZE)
        r.draw(dl, BG)
        return r.read_pixels(), cam, dl


def _inside(ring_xz, height):
    """World points strictly inside a prism: the ring shrunk towards its centre, several heights."""
    ring = np.asarray(ring_xz, float)
    c = ring.mean(0)
    pts = []
    for s in (0.0, 0.35, 0.65):
        for q in ring:
            x, z = c + s * (q - c)
            for y in (0.2, 0.5, 0.8):
                pts.append((x, y * height, z))
    return np.array(pts)


def _box_ring(center, size, yaw_deg):
    a = np.radians(yaw_deg)
    c, s = np.cos(a), np.sin(a)
    loc = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * np.asarray(size) / 2
    return np.stack([center[0] + c * loc[:, 0] + s * loc[:, 1], center[1] - s * loc[:, 0] + c * loc[:, 1]], 1)


def _pixels(img, cam, pts):
    px = cam.project(pts, SIZE)
    ij = np.floor(px).astype(int)
    assert ((ij >= 0) & (ij < SIZE)).all(), "test geometry must be in view"
    return img[ij[:, 1], ij[:, 0]].astype(int)


def _objects():
    (cx, cz), cr, ch = CIRCLE
    a = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    out = {"circle": (_inside(np.stack([cx + cr * np.cos(a), cz + cr * np.sin(a)], 1), ch), None),
           "box": (_inside(_box_ring(BOX[0], BOX[1], BOX[2]), BOX[3]), None),
           "polygon": (_inside(POLY[0], POLY[1]), None)}
    for fmt, ((x, z), rgb) in PROPS.items():
        out[f"prop.{fmt}"] = (_inside(_box_ring((x, z), (1.0, 1.0), 0.0), 1.0), rgb)
    return out


@pytest.fixture(scope="module")
def world_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("world")


@pytest.mark.parametrize("mode", list(MODES))
def test_obstacles_and_props_cover_their_pixels_in_every_mode(world_dir, mode):
    img, cam, dl = _frame(_scene(world_dir, mode))
    bg = np.round(np.asarray(BG) * 255).astype(int)
    for name, (pts, rgb) in _objects().items():
        pix = _pixels(img, cam, pts)
        off = np.abs(pix - bg).max(axis=1)
        assert (off > 12).all(), f"{mode}: {name}: {int((off <= 12).sum())} of {len(pix)} pixels show the background"
        if rgb is not None:  # the prop's own colour: its dominant channel stays dominant when lit
            k = int(np.argmax(rgb))
            others = [c for c in range(3) if rgb[c] < 0.5]
            assert (pix[:, k][:, None] > pix[:, others] + 20).all(), f"{mode}: {name}: colour {pix[:3].tolist()}"
        else:
            assert (pix[:, 0] >= pix[:, 2]).all(), f"{mode}: {name}: expected a warm solid/grey prop colour"
    # the sky above the objects is background: nothing is drawn where nothing is
    assert np.abs(img[:8].astype(int) - bg).max() <= 1
    assert dl.stats["props"] > 0 and dl.stats["props_instances"] == len(PROPS) + 1  # + the obstacle solids


def test_ground_is_drawn_unless_switched_off(world_dir):
    bg = np.round(np.asarray(BG) * 255).astype(int)
    on, cam, dl = _frame(_scene(world_dir, "none", ground=True))
    off, _, dl_off = _frame(_scene(world_dir, "none", ground=False))
    # a patch of floor between the objects and the camera
    floor = _pixels(on, cam, np.array([[x, 0.0, z] for x in (-2.0, 0.0, 2.0) for z in (4.5, 5.5)]))
    assert (np.abs(floor - bg).max(axis=1) > 30).all()
    assert (_pixels(off, cam, np.array([[0.0, 0.0, 5.0]])) == bg).all()
    assert any(b.rep == "world:ground" for b in dl.batches)
    assert not any(b.rep == "world:ground" for b in dl_off.batches)
    # the grid: the floor is not one flat colour (lines every metre)
    lo = on[int(0.8 * SIZE[1]):, :, :].astype(int)
    assert lo.std(axis=(0, 1)).max() > 1.0


def test_ground_far_from_the_origin_draws_as_near_it(gl_ctx):
    from lod.props.select import WorldSelector
    from lod.props.solids import GroundRep
    from lod.view import Camera
    from render.renderer import Renderer

    from lod.drawlist import DrawList

    sel = WorldSelector([], GroundRep())
    imgs = []
    with Renderer(SIZE, ctx=gl_ctx) as r:
        r.upload(sel.ground)
        for off in (0.0, 1e6, 1e9):
            cam = Camera.look_at((off + 0.3, 3.0, off + 0.7), (off + 0.3, 0.0, off - 10.7), fov_y=50.0, far=800.0)
            batches, _ = sel.select(cam, SIZE)
            dl = DrawList(origin=cam.position, view=cam.view_matrix().astype(np.float32),
                          proj=cam.projection(SIZE[0] / SIZE[1]).astype(np.float32), size=SIZE, batches=batches)
            r.draw(dl, BG)
            imgs.append(r.read_pixels().astype(int))
    assert imgs[0][-20:].std() > 1.0  # grid lines near the camera
    for im in imgs[1:]:
        assert np.abs(im - imgs[0]).mean() < 0.5 and np.abs(im - imgs[0]).max() <= 40


def test_ground_covers_the_frame_to_the_horizon(gl_ctx):
    """A level camera sees ground on every pixel below the horizon (up to the few rows where the
    plane meets the far plane) and background above it, also 1e7 m from the origin."""
    from lod.drawlist import DrawList
    from lod.props.select import WorldSelector
    from lod.props.solids import GroundRep
    from lod.view import Camera
    from render.renderer import Renderer

    sel = WorldSelector([], GroundRep())
    bg = np.round(np.asarray(BG) * 255).astype(int)
    with Renderer(SIZE, ctx=gl_ctx) as r:
        r.upload(sel.ground)
        for off in (0.0, 1e7):
            cam = Camera.look_at((off, 1.7, off), (off + 10.0, 1.7, off), fov_y=50.0, far=1000.0)
            batches, _ = sel.select(cam, SIZE)
            dl = DrawList(origin=cam.position, view=cam.view_matrix().astype(np.float32),
                          proj=cam.projection(SIZE[0] / SIZE[1]).astype(np.float32), size=SIZE, batches=batches)
            r.draw(dl, BG)
            img = r.read_pixels().astype(int)
            ground = np.abs(img - bg).max(axis=2) > 8
            horizon = SIZE[1] // 2  # the horizon of a level camera is the middle row
            # the plane ends at the far plane: 1.7 m below the eye at 1000 m, i.e. 1.7 / 1000 * focal px below
            gap = int(np.ceil(1.7 / 1000.0 * SIZE[1] / (2 * np.tan(np.radians(25.0))))) + 2
            assert ground[horizon + gap:].all(), off
            assert not ground[:horizon - 1].any(), off
