"""Per-agent colour variation in rendered pixels (render/tint.py, [[characters]] variation): an agent
has the same colour in every LOD mode at the same frame, the colours are a function of the scene seed,
and the fly-through's debug colours (lod.debug_colors) reach mode points too."""
import numpy as np
import pytest
from crowd_testutil import tiny_scene

from crowd.engine import Engine
from crowd.scene import load_scene
from lod.debug_colors import REPRESENTATION_COLORS, TINT_WEIGHT, apply_tints
from lod.view import Camera

MODES = ("none", "triangles", "points", "clusters", "auto")
#: pixels of error of the coarse pass (coarser chain levels, cluster cuts and point nodes)
COARSE_POE = 6.0
W, H = 240, 160
#: a strong variation, so that agents differ far more than the LOD modes' own colour differences
STRONG = 'variation = { hue = 0.45, saturation = 0.3, value = 0.3, regions = ["shirt", "trousers"] }'


def _scene(tmp_path, variation=STRONG, seed=1, name="v.toml"):
    text = tiny_scene(replace={"rows = 2": "rows = 1", "cols = 2": "cols = 4", "seed = 1": f"seed = {seed}",
                               'triangles = 600': f'triangles = 600\nseed = 7\n{variation}',
                               # agents against a black background: their pixels are the ones above black
                               "png_every = 1": "png_every = 1\nground = false"})
    p = tmp_path / name
    p.write_text(text)
    return load_scene(p)


def _camera(e):
    pos = np.asarray(e.world.state.position, np.float64)
    c = pos.mean(axis=0)
    return Camera.look_at(c + (0.0, 1.1, 5.5), c + (0.0, 0.95, 0.0), fov_y=50)


def _agent_boxes(e, cam):
    """Per agent, the pixel box around its shirt and trousers (0.55 m .. 1.45 m up, +-0.18 m)."""
    pos = np.asarray(e.world.state.position, np.float64)
    boxes = []
    for p in pos:
        corners = np.array([p + (-0.18, 0.55, 0.0), p + (0.18, 1.45, 0.0)])
        px = cam.project(corners, (W, H))
        x0, x1 = sorted(px[:, 0])
        y0, y1 = sorted(px[:, 1])
        boxes.append((int(x0), int(np.ceil(x1)), int(y0), int(np.ceil(y1))))
    return boxes


def _agent_means(img, boxes):
    out = []
    for x0, x1, y0, y1 in boxes:
        patch = img[max(y0, 0):y1, max(x0, 0):x1].reshape(-1, 3).astype(np.float64)
        fg = patch[patch.max(axis=1) > 12]
        assert fg.shape[0] > 30, "the agent covers too few pixels of its box"
        out.append(fg.mean(axis=0))
    return np.array(out)


def _render(e, cam, mode, color_by="none"):
    r = e._open_renderer()
    e.set_lod_mode(mode)
    dl = e.select(cam, (W, H))
    apply_tints(dl, color_by, statics=e.static_keys)
    r.draw(dl, (0.0, 0.0, 0.0))
    return r.read_pixels(), dl


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    """Frame 0 of the strong-variation scene and of the same scene without variation, in every mode."""
    tmp = tmp_path_factory.mktemp("variation")
    out = {}
    for key, var in (("on", STRONG), ("off", "variation = false")):
        with Engine(_scene(tmp, var, name=f"{key}.toml"), overrides={"size": (W, H)}, quiet=True) as e:
            cam = _camera(e)
            boxes = _agent_boxes(e, cam)
            for m in MODES:
                img, dl = _render(e, cam, m)
                out[key, m] = (img, dl)
            drawer = e.renderer.uploaded_drawer("points")
            drawer.path = "gl_points"  # the GL_POINTS reference path of the point drawer
            out[key, "points", "gl_points"] = _render(e, cam, "points")
            drawer.path = None
            e.settings.poe = COARSE_POE  # coarser levels of every mode at the same view
            for m in MODES[1:]:
                out[key, m, "coarse"] = _render(e, cam, m)
            e.settings.poe = 1.0
            out["boxes"] = boxes
    return out


def test_same_agent_same_colour_in_every_mode(frames):
    boxes = frames["boxes"]
    ref = _agent_means(frames["on", "none"][0], boxes)
    plain = _agent_means(frames["off", "none"][0], boxes)
    # the variation is visible (agents move off their untinted colour), and agents differ from each other
    shift = np.abs(ref - plain).max(axis=1)
    assert shift.max() > 40 and shift.mean() > 15, shift
    d = np.abs(ref[:, None] - ref[None]).max(axis=2)
    assert d[~np.eye(4, dtype=bool)].min() > 12, d
    for m in [*MODES[1:], *((m, "coarse") for m in MODES[1:]), ("points", "gl_points")]:
        img, dl = frames[("on", m) if isinstance(m, str) else ("on", *m)]
        off_img = frames[("off", m) if isinstance(m, str) else ("off", *m)][0]
        assert dl.n_instances == 4
        if m in ("points", ("points", "gl_points")):  # the splat's colour pass (GL points) is compared too
            assert dl.points > 0
        means = _agent_means(img, boxes)
        # a LOD mode changes the geometry a little, never the tint: within 7 levels of 255 per channel
        # (measured: at most 4.1, triangle chain level 2), 10 for the splats of samples that follow the animation
        # (measured 8.6: their splats cover the limbs' edges a little wider; the tint itself is checked below)
        bound = 10 if m in ("points", ("points", "gl_points"), ("points", "coarse")) else 7
        assert np.abs(means - ref).max() < bound, (m, means - ref)
        off = _agent_means(off_img, boxes)
        # and the tint moves every agent's colour as it does at full detail
        assert np.abs((means - off) - (ref - plain)).max() < 7, m


def test_variation_depends_on_the_seed_only(tmp_path):
    imgs = {}
    for tag, seed in (("a", 1), ("b", 1), ("c", 2)):
        with Engine(_scene(tmp_path, seed=seed, name=f"{tag}.toml"), overrides={"size": (W, H)}, quiet=True) as e:
            cam = _camera(e)
            boxes = _agent_boxes(e, cam)
            imgs[tag] = (_render(e, cam, "none")[0], boxes)
    assert np.array_equal(imgs["a"][0], imgs["b"][0])
    a, c = _agent_means(*imgs["a"]), _agent_means(*imgs["c"])
    assert np.abs(a - c).max(axis=1).max() > 20


def test_debug_colour_in_every_mode_points_included(tmp_path):
    with Engine(_scene(tmp_path, "variation = false"), overrides={"size": (W, H)}, quiet=True) as e:
        cam = _camera(e)
        boxes = _agent_boxes(e, cam)
        for mode in ("points", "none", "triangles", "clusters"):
            plain, _ = _render(e, cam, mode)
            tinted, dl = _render(e, cam, mode, "representation")
            assert all(b.representation == mode for b in dl.batches)
            if mode == "points":
                assert dl.points > 0  # splats, not only the hierarchy's triangles
            rgb = np.asarray(REPRESENTATION_COLORS[mode])
            p, t = _agent_means(plain, boxes), _agent_means(tinted, boxes)
            # every agent's colour moved to the debug colour: lit (u_ambient + diffuse) times
            # mix(base, debug, TINT_WEIGHT), whose chromaticity is nearly the debug colour's
            chrom = t / t.sum(axis=1, keepdims=True)
            assert np.abs(chrom - rgb / rgb.sum()).max() < 0.08, (mode, chrom)
            assert np.abs(t - p).max(axis=1).min() > 12, mode
    assert TINT_WEIGHT > 0.5


@pytest.mark.parametrize("line,needle", [
    ("variation = 3", "characters[0].variation: expected a table"),
    ("variation = { hue = 0.7 }", "characters[0].variation.hue"),
    ("variation = { tone = 0.1 }", "characters[0].variation.tone: unknown key"),
    ("variation = { palette = [[1.0, 0.5]] }", "characters[0].variation.palette"),
    ("variation = { palette = [] }", "characters[0].variation.palette"),
    ('variation = { regions = ["hat"] }', "characters[0].variation.regions"),
])
def test_bad_variation_is_one_line_exit_2(tmp_path, line, needle):
    from crowd_testutil import run_cli

    p = tmp_path / "bad.toml"
    p.write_text(tiny_scene(replace={'triangles = 600': f'triangles = 600\n{line}'}))
    r = run_cli("validate", p)
    assert r.returncode == 2 and needle in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr


def test_variation_defaults_and_masks(tmp_path):
    from crowd.characters import build_character
    from crowd.scene import DEFAULT_VARIATION

    s = _scene(tmp_path, variation="")
    assert dict(s.characters[0].variation) == DEFAULT_VARIATION  # on by default for a generated humanoid
    assert _scene(tmp_path, "variation = false").characters[0].variation is None
    ch = build_character(s.characters[0])
    alpha = ch.mesh.colors[:, 3]
    want = ch.regions["shirt"] | ch.regions["trousers"]
    assert np.array_equal(alpha, want.astype(np.float32)) and 0 < want.mean() < 1
    p = tmp_path / "q.toml"
    p.write_text(tiny_scene(replace={'generator = "humanoid"': 'generator = "quadruped"'}))
    assert load_scene(p).characters[0].variation is None  # other characters: off unless asked
    p.write_text(tiny_scene(replace={'generator = "humanoid"': 'generator = "quadruped"\nvariation = { value = 0.2 }'}))
    q = load_scene(p).characters[0]
    assert dict(q.variation)["regions"] is None
    assert (build_character(q).mesh.colors[:, 3] == 1.0).all()  # the whole mesh varies


def _two_material_glb(path):
    """A static two-primitive glTF model: primitive 0 with material 0 (red), primitive 1 with material 1 (green)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fixtures"))
    from gltf_builder import GltfBuilder, write_glb

    b = GltfBuilder()
    prims = []
    for k in range(2):
        pos = np.array([[k, 0, 0], [k + 1, 0, 0], [k, 1, 0]], np.float32)
        prims.append({"attributes": {"POSITION": b.acc(pos, "VEC3", min=pos.min(0).tolist(), max=pos.max(0).tolist())},
                      "indices": b.acc(np.array([0, 1, 2], np.uint16), "SCALAR"), "material": k})
    b.gltf.update(meshes=[{"primitives": prims}], nodes=[{"mesh": 0}], scenes=[{"nodes": [0]}], scene=0,
                  materials=[{"pbrMetallicRoughness": {"baseColorFactor": c}} for c in ([1, 0, 0, 1], [0, 1, 0, 1])])
    return write_glb(path, *b.finish())


def test_gltf_material_regions(tmp_path):
    from crowd.characters import build_character
    from crowd.errors import AssetError

    glb = _two_material_glb(tmp_path / "two.glb")
    p = tmp_path / "g.toml"
    for regions, want in (('["material:1"]', [0, 0, 0, 1, 1, 1]), ("", [1] * 6)):
        line = f"variation = {{ hue = 0.2{', regions = ' + regions if regions else ''} }}"
        p.write_text(tiny_scene(replace={'generator = "humanoid"': f'file = "{glb.name}"\n{line}',
                                         "triangles = 600": ""}))
        ch = build_character(load_scene(p).characters[0])
        assert sorted(ch.regions) == ["material:0", "material:1"]
        assert ch.mesh.colors[:, 3].tolist() == want
        assert np.allclose(ch.mesh.colors[:3, :3], [1, 0, 0]) and np.allclose(ch.mesh.colors[3:, :3], [0, 1, 0])
    p.write_text(tiny_scene(replace={'generator = "humanoid"': f'file = "{glb.name}"\n'
                                     'variation = { hue = 0.2, regions = ["material:7"] }', "triangles = 600": ""}))
    with pytest.raises(AssetError, match=r"variation.regions: 'material:7' is not a region of this model; "
                                         r"it has: material:0, material:1"):
        build_character(load_scene(p).characters[0])
    p.write_text(tiny_scene(replace={'generator = "humanoid"': f'file = "{glb.name}"\n'
                                     'variation = { regions = ["shirt"] }', "triangles = 600": ""}))
    from crowd.errors import SceneError

    with pytest.raises(SceneError, match=r'variation.regions: expected a non-empty list of "material:N"'):
        load_scene(p)
