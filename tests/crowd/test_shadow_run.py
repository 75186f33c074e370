"""Scene keys of the light and shadows, and characters casting into the shadow map in a run (modes none, triangles
chains and clusters; points fall back to blobs)."""
import numpy as np
import pytest
from crowd_testutil import run_cli, tiny_scene

from crowd.engine import Engine
from crowd.scene import load_scene
from lod.view import Camera

#: a flat ground (the terrain) under the tiny scene's 2 x 2 agents at x, z in {0, 1.5}, seen from straight above
FLAT = ("\n[terrain]\nsize = [20.0, 20.0]\norigin = [-10.0, 0.0, -10.0]\nresolution = 9\nheight_scale = 0.0\n")
ABOVE = {'position = [1.0, 2.0, 7.0]\ntarget = [1.0, 0.8, 1.0]\n':
         'position = [0.75, 12.0, 0.76]\ntarget = [0.75, 0.0, 0.75]\nfov = 30.0\n',
         "size = [64, 48]": "size = [160, 120]"}


@pytest.mark.parametrize("key, value, msg", [
    ("light_dir", "[0.0, 0.0, 0.0]", "render.light_dir: expected a non-zero direction"),
    ("light_dir", "[1.0, 2.0]", "render.light_dir"),
    ("light_color", "[1.0, -0.5, 1.0]", "render.light_color"),
    ("ambient", "-1.0", "render.ambient"),
    ("shadows", '"soft"', "render.shadows: expected one of 'blob', 'map', 'none'"),
    ("shadow_distance", "0.0", "render.shadow_distance"),
    ("shadow_map_size", "100000", "render.shadow_map_size"),
])
def test_bad_light_and_shadow_keys_are_one_line_exit_2(write_scene, tmp_path, key, value, msg):
    scene = write_scene(tiny_scene(replace={"png_every = 1": f"png_every = 1\n{key} = {value}"}))
    r = run_cli("run", scene, "--out", tmp_path / "out")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and msg in lines[0] and "Traceback" not in r.stderr, r.stderr
    assert not (tmp_path / "out").exists()


def test_light_keys_reach_the_renderer(write_scene):
    scene = load_scene(write_scene(tiny_scene(replace={
        "png_every = 1": "png_every = 1\nlight_dir = [0.0, 3.0, 4.0]\nlight_color = [1.0, 0.5, 0.25]\n"
                         "ambient = 0.2\nshadows = \"map\"\nshadow_map_size = 512"})))
    assert scene.render.light.direction == pytest.approx((0.0, 0.6, 0.8))
    with Engine(scene, quiet=True) as e:
        lighting = e._open_renderer().lighting
        assert (lighting.mode, lighting.map_size, lighting.light.color, lighting.light.ambient) == \
            ("map", 512, (1.0, 0.5, 0.25), 0.2)
    assert load_scene(write_scene(tiny_scene(), "d.toml")).render.shadows == "blob"  # the default


def _frame(write_scene, mode: str, shadows: str, name: str, append: str = FLAT) -> tuple:
    """One frame seen from above; ``append`` = FLAT: on the flat terrain, "": on the world's ground plane."""
    text = tiny_scene(replace={**ABOVE, "frames = 3": "frames = 1", 'mode = "none"': f'mode = "{mode}"',
                               "png_every = 1": f'png_every = 1\nlight_dir = [1.0, 1.0, 0.0]\nshadows = "{shadows}"'},
                      append=append)
    scene = load_scene(write_scene(text, name))
    with Engine(scene, quiet=True) as e:
        r = e._open_renderer()
        e.step()
        cam = e.camera_at(e.world.time)
        r.draw(e.select(cam, scene.render.size), scene.render.background)
        img = r.read_pixels().astype(np.float64).mean(axis=-1)
        pos = np.asarray(e.world.state.position, np.float64)
        return img, cam, pos, dict(r.lighting.last_counts)


def _at(img, cam: Camera, pts) -> np.ndarray:
    uv = cam.project(np.asarray(pts, np.float64), (img.shape[1], img.shape[0]))
    return np.array([img[int(v), int(u)] for u, v in uv])


@pytest.mark.parametrize("mode", ["none", "triangles", "clusters"])
def test_characters_cast_into_the_shadow_map(write_scene, mode):
    """Light 45 degrees from the zenith towards +x: each agent's shadow lies on the ground 0.3 .. 1.2 m towards
    -x of its feet (the torso's shadow) and darkens it against shadows = none; the ground 0.7 m towards +x (between
    the agents, in front of the light) stays as it was."""
    plain, cam, pos, _ = _frame(write_scene, mode, "none", "a.toml")
    shaded, _, pos2, counts = _frame(write_scene, mode, "map", "b.toml")
    assert np.array_equal(pos, pos2) and counts["casters"] == 4 and counts["blobs"] == 0
    behind = [p + d for p in pos for d in ([-0.6, 0.0, 0.0], [-0.9, 0.0, 0.0])]
    front = [p + [0.7, 0.0, 0.45] for p in pos]
    dark, before = _at(shaded, cam, behind), _at(plain, cam, behind)
    assert (dark < 0.85 * before).all(), (dark, before)
    assert np.abs(_at(shaded, cam, front) - _at(plain, cam, front)).max() <= 3


def test_point_representations_fall_back_to_blobs_in_map_mode(write_scene):
    _, _, _, counts = _frame(write_scene, "points", "map", "c.toml")
    assert counts == {"blobs": 4, "blobs_drawn": 4, "casters": 0}


def test_map_mode_with_mixed_triangle_and_cluster_batches_keeps_every_silhouette(write_scene):
    """One frame drawn with full-detail batches (agents 2, 3) and cluster cuts (all agents): casting the cluster cuts
    rebuilds the shared skinning palette, so the renderer's own batches must get theirs back. The shadow map may
    only darken: the silhouettes (pixels that differ from the background) are those of shadows = none, and no pixel
    is brighter."""
    text = tiny_scene(replace={"frames = 3": "frames = 1", 'mode = "none"': 'mode = "clusters"',
                               "size = [64, 48]": "size = [192, 144]",
                               "png_every = 1": 'png_every = 1\nlight_dir = [1.0, 1.0, 0.0]'})
    scene = load_scene(write_scene(text, "m.toml"))
    with Engine(scene, quiet=True) as e:
        r = e._open_renderer()
        e.set_lod_mode("none")  # uploads the full-detail reps too
        e.step()
        cam = e.camera_at(e.world.time)
        size = scene.render.size
        full = e._modes["none"][1].select(e.world.state, cam, size)
        cut = e._modes["clusters"][1].select(e.world.state, cam, size)
        keep = []
        for b in full.batches:
            m = np.isin(b.instance_ids, [2, 3])  # not the first: their palette rows differ from the cuts'
            if m.any():
                b.instance_ids, b.instance_data = b.instance_ids[m], b.instance_data[m]
                keep.append(b)
        assert keep and cut.batches
        cut.batches = keep + list(cut.batches)
        images = {}
        for mode in ("none", "map"):
            r.lighting.configure(mode=mode)
            r.draw(cut, scene.render.background)
            images[mode] = r.read_pixels().astype(np.int16)
        assert r.lighting.last_counts["casters"] == 6
    bg = np.round(np.asarray(scene.render.background) * 255).astype(np.int16)
    fg = {m: np.abs(img - bg).max(axis=-1) > 2 for m, img in images.items()}
    # (without the palette rebuild agents 2 and 3 take agents 0 and 1's poses: ~5 % of the silhouette pixels move)
    assert fg["none"].sum() > 500 and (fg["none"] != fg["map"]).sum() <= 0.01 * fg["none"].sum()
    assert (images["map"] - images["none"]).max() <= 3


def test_characters_shadows_fall_on_the_world_ground(write_scene):
    """Without a terrain the world's ground plane (render.world.draw) is the floor: it receives the characters' shadow
    map (darker 0.6 .. 0.9 m towards -x of each agent, unchanged 0.7 m towards +x) and lies under their blob
    shadows (darker around each agent's feet than the bare ground, unchanged 1 m away)."""
    plain, cam, pos, _ = _frame(write_scene, "none", "none", "g0.toml", append="")
    mapped, _, pos2, counts = _frame(write_scene, "none", "map", "g1.toml", append="")
    assert np.array_equal(pos, pos2) and counts["casters"] == 4
    behind = [p + d for p in pos for d in ([-0.6, 0.0, 0.0], [-0.9, 0.0, 0.0])]
    front = [p + [0.7, 0.0, 0.45] for p in pos]
    dark, before = _at(mapped, cam, behind), _at(plain, cam, behind)
    assert (dark < 0.85 * before).all(), (dark, before)
    assert np.abs(_at(mapped, cam, front) - _at(plain, cam, front)).max() <= 3
    blob, _, pos3, counts = _frame(write_scene, "none", "blob", "g2.toml", append="")
    assert np.array_equal(pos, pos3) and counts["blobs"] == 4
    # a ring 0.25 m around each agent's feet: where the body does not stand in front of it, the blob darkens the
    # ground (at least 8 of 24 points by more than 10 levels; no point gets brighter)
    a = np.linspace(0.0, 2 * np.pi, 24, endpoint=False)
    for p in pos:
        ring = p + 0.25 * np.stack([np.cos(a), np.zeros_like(a), np.sin(a)], 1)
        diff = _at(blob, cam, ring) - _at(plain, cam, ring)
        assert (diff < -10).sum() >= 8 and diff.max() <= 1, diff
    far = [p + [0.75, 0.0, 0.75] for p in pos[:1]] + [pos[0] + [-1.0, 0.0, -1.0]]
    assert np.abs(_at(blob, cam, far) - _at(plain, cam, far)).max() <= 1
