"""Hard cases: small scenes and assets, each with the invariant it must keep.

Run for many frames each (kept small so the suite stays fast on llvmpipe):
no NaN/Inf in state, DrawList instance data (debug renderers refuse them) or
images; bounded speeds and errors. See issue 10.
"""
from __future__ import annotations

import numpy as np
import pytest

from hc_util import check_frame, crowd, look, render_frames
from tiny_characters import tiny_keyframed, tiny_skinned

from sim.character import KeyframedCharacter
from sim.clip import Channel, Clip
from sim.keyframes import Keyframe, KeyframeAnimation, Segment
from sim.mesh import Mesh, vertex_normals
from sim.skinning import skin, skin_reference

FRAMES = 24


def _sphere(n_lat=8, n_lon=12, radius=1.0):
    lat = np.linspace(0, np.pi, n_lat + 1)
    lon = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    p = np.array([[np.sin(a) * np.cos(b), np.cos(a), np.sin(a) * np.sin(b)] for a in lat for b in lon]) * radius
    tri = []
    for i in range(n_lat):
        for j in range(n_lon):
            a, b = i * n_lon + j, i * n_lon + (j + 1) % n_lon
            tri += [(a, b + n_lon, b), (a, a + n_lon, b + n_lon)]  # pole rows: zero-area triangles
    return p.astype(np.float32), np.array(tri, np.uint32)


def _kf(p, idx):
    col = np.tile([0.7, 0.6, 0.2, 1.0], (len(p), 1)).astype(np.float32)
    return Keyframe(p.astype(np.float32), vertex_normals(p, idx), col, idx)


def test_sphere_shrinking_to_a_hundredth_of_its_area(gl_ctx):
    p, idx = _sphere()
    scales = [1.0, 0.4, 0.1]  # area 1 -> 1/100
    kfs = [_kf(p * s + np.array([0, 1, 0], np.float32), idx) for s in scales]
    ident = np.arange(len(p), dtype=np.int32)
    segs = [Segment(ident, ident, idx.copy()) for _ in range(3)]
    anim = KeyframeAnimation("shrink", np.array([0.0, 0.5, 1.0]), kfs, segs, duration=1.5, loop=True)
    ch = KeyframedCharacter("ball", {"shrink": anim})
    st = crowd(9, spacing=3.0)
    images, reps, sel = render_frames(gl_ctx, [ch], st, look((3, 4, 14), (3, 1, 3)), np.linspace(0, 1.5, FRAMES))
    assert all(im.std() > 0 for im in images)  # the spheres are drawn in every frame
    rep = reps[0]
    # whole-segment bounding spheres contain both ends of every segment
    for s in range(rep.n_parts):
        c, r = rep.part_sphere()[s, :3], rep.part_sphere()[s, 3]
        a, b = kfs[s].positions, kfs[(s + 1) % 3].positions
        assert np.linalg.norm(np.vstack([a, b]) - c, axis=1).max() <= r * (1 + 1e-5)
    # the smallest sphere really has 1/100 of the area: radius 0.1
    np.testing.assert_allclose(np.linalg.norm(kfs[2].positions - [0, 1, 0], axis=1).max(), 0.1, rtol=1e-5)


def _degenerate_mesh():
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0],
                  [2, 0, 0], [2, 0, 0],          # coincident vertices
                  [3, 0, 0], [3 + 1e-7, 1, 0],   # sliver
                  [0, 0, 1], [0, 1, -1]], np.float32)
    t = np.array([[0, 1, 2], [1, 3, 2],
                  [0, 1, 2],              # duplicate
                  [0, 0, 1],              # zero area (repeated index)
                  [1, 4, 5],              # zero area (coincident vertices)
                  [4, 6, 7],              # sliver
                  [0, 1, 8], [0, 1, 9],   # non-manifold edge 0-1 (four triangles)
                  ], np.uint32)
    return p, t


def test_degenerate_triangles_normals_finite_and_render(gl_ctx):
    from lod.full.mode import NoLodSelector
    from lod.full.reps import build_static_rep
    from render.renderer import Renderer
    from sim.state import CrowdState

    p, t = _degenerate_mesh()
    n = vertex_normals(p, t)
    assert np.isfinite(n).all()
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-5)
    # coincident vertices 4 and 5 get finite normals, isolated vertices (none here) +Y
    mesh = Mesh(positions=p, indices=t)
    rep = build_static_rep(mesh, key="hc:degenerate")
    assert np.isfinite(rep.sphere).all()
    sel = NoLodSelector([rep])
    st = CrowdState.empty(4)
    st.position[:, 0] = np.arange(4) * 4.0
    cam = look((6, 2, 8), (6, 0.5, 0))
    with Renderer((64, 48), ctx=gl_ctx, debug=True) as r:
        r.upload(rep)
        for _ in range(FRAMES // 4):
            dl = sel.select(st, cam, (64, 48))
            r.draw(dl)
        assert r.read_pixels().std() > 0
    # open + non-manifold skinned: CPU skinning finite
    j = np.zeros((len(p), 4), np.uint16)
    w = np.zeros((len(p), 4), np.float32)
    w[:, 0] = 1
    sm = Mesh(positions=p, indices=t, joints=j, weights=w)
    pos, nrm = skin(sm, np.eye(4)[None])
    assert np.isfinite(pos).all() and np.isfinite(nrm).all()


def test_skin_weights_repaired_or_refused_in_gltf(tmp_path):
    """Weights not summing to 1 are renormalised, all-zero and negative ones are
    repaired with a warning naming the file and the vertex count, NaN is refused."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "sim" / "gltf"))
    from test_fuzz_gltf import BASE_BLOB, BASE_JSON, glb_bytes  # noqa: E402
    from sim.errors import AssetError
    from sim.gltf.load import load_gltf

    wacc = BASE_JSON["accessors"][2]
    off = BASE_JSON["bufferViews"][wacc["bufferView"]]["byteOffset"]

    def with_weights(w, name):
        blob = bytearray(BASE_BLOB)
        blob[off:off + 64] = np.asarray(w, np.float32).tobytes()
        path = tmp_path / name
        path.write_bytes(glb_bytes(BASE_JSON, bytes(blob)))
        return path

    # not summing to 1: renormalised
    ch = load_gltf(with_weights([[2, 0, 0, 0], [0.3, 0.3, 0, 0], [0, 5, 0, 0], [0.1, 0.1, 0, 0]], "sum.glb"))
    np.testing.assert_allclose(ch.mesh.weights.sum(1), 1.0, atol=1e-6)
    np.testing.assert_allclose(ch.mesh.weights[1, :2], [0.5, 0.5], atol=1e-6)
    # all zero: warning with the file and count
    with pytest.warns(UserWarning, match=r"zero\.glb: 2 vertices have all-zero skin weights"):
        ch = load_gltf(with_weights([[0, 0, 0, 0], [0.5, 0.5, 0, 0], [0, 0, 0, 0], [1, 0, 0, 0]], "zero.glb"))
    np.testing.assert_allclose(ch.mesh.weights.sum(1), 1.0, atol=1e-6)
    # negative: clipped with a warning naming the file and the count
    with pytest.warns(UserWarning, match=r"neg\.glb: .*1 vertices have negative skin weights"):
        ch = load_gltf(with_weights([[1, 0, 0, 0], [1.5, -0.5, 0, 0], [0, 1, 0, 0], [1, 0, 0, 0]], "neg.glb"))
    assert (ch.mesh.weights >= 0).all()
    np.testing.assert_allclose(ch.mesh.weights.sum(1), 1.0, atol=1e-6)
    # NaN: refused in one sentence
    with pytest.raises(AssetError, match=r"nan\.glb: .*WEIGHTS_0.* NaN or infinite"):
        load_gltf(with_weights([[np.nan, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0], [1, 0, 0, 0]], "nan.glb"))


def test_mesh_level_bad_weights_finite_in_rep_and_cpu_skinning(gl_ctx):
    """A Mesh built in code with zero or negative weights: the full-detail rep
    repairs them (rows sum to 1 or 0) and CPU skinning stays finite."""
    ch = tiny_skinned()
    w = ch.mesh.weights.copy()
    w[0] = 0.0
    w[1] = (2.0, -1.0, 0.0, 0.0)
    w[2] = (3.0, 3.0, 0.0, 0.0)
    ch.mesh.weights = w
    pos, nrm = skin(ch.mesh, ch.skeleton.skinning_matrices(*ch.skeleton.rest_pose()))
    assert np.isfinite(pos).all() and np.isfinite(nrm).all()
    st = crowd(4, spacing=2.0)
    images, reps, _ = render_frames(gl_ctx, [ch], st, look((1, 2, 8), (1, 1.5, 0)), np.linspace(0, 1, 8))
    s = reps[0].weights.sum(1)
    assert np.isfinite(reps[0].weights).all() and ((np.abs(s - 1) < 1e-5) | (s == 0)).all()


def test_mesh_level_weights_repaired_like_the_gltf_importer(gl_ctx):
    """sim.skin_weights: the glTF importer's policy for meshes built in code:
    NaN refused in one sentence, negative clipped and all-zero rebound with a
    warning naming the asset and vertex count, rows renormalised."""
    from sim.errors import AssetError
    from sim.skin_weights import repair_mesh_weights

    ch = tiny_skinned("coded")
    w = ch.mesh.weights.copy()
    w[0] = 0.0
    w[1] = 0.0
    w[2] = (2.0, -1.0, 0.0, 0.0)
    w[3] = (3.0, 3.0, 0.0, 0.0)
    ch.mesh.weights = w
    with pytest.warns(UserWarning) as rec:
        counts = repair_mesh_weights(ch.mesh, "coded", n_joints=ch.skeleton.n_joints)
    msgs = [str(r.message) for r in rec]
    assert any(m.startswith("coded: 1 vertices have negative skin weights") for m in msgs)
    assert any(m.startswith("coded: 2 vertices have all-zero skin weights") for m in msgs)
    assert counts == {"negative": 1, "zero": 2, "renormalised": 2}
    np.testing.assert_allclose(ch.mesh.weights.sum(1), 1.0, atol=1e-6)
    assert (ch.mesh.weights >= 0).all() and ch.mesh.weights.dtype == np.float32
    pos, nrm = skin(ch.mesh, ch.skeleton.skinning_matrices(*ch.skeleton.rest_pose()))
    assert np.isfinite(pos).all() and np.isfinite(nrm).all()
    st = crowd(4, spacing=2.0)
    render_frames(gl_ctx, [ch], st, look((1, 2, 8), (1, 1.5, 0)), np.linspace(0, 1, 8))
    # NaN: refused in one sentence naming the asset and the count
    bad = tiny_skinned("nanny")
    bad.mesh.weights[[3, 5]] = (np.nan, 1.0, 0.0, 0.0)
    with pytest.raises(AssetError, match=r"^nanny: 2 vertices have NaN or infinite skin weights; [^\n]*$"):
        repair_mesh_weights(bad.mesh, "nanny")
    # a joint index past the skeleton is refused too
    bad2 = tiny_skinned("far")
    bad2.mesh.joints[0, 0] = 9
    with pytest.raises(AssetError, match="far: skin joint indices reach 9"):
        repair_mesh_weights(bad2.mesh, "far", n_joints=3)


def test_joint_scaled_to_zero_skinning_finite(gl_ctx):
    ch = tiny_skinned()
    t = np.array([0.0, 0.5, 1.0])
    ch.clips["vanish"] = Clip("vanish", 1.0, [Channel(1, "scale", t, np.array([[1, 1, 1], [0, 0, 0], [1, 1, 1.0]]))],
                              loop=True)
    for tt in np.linspace(0, 1, FRAMES):
        mats = ch.skeleton.skinning_matrices(*ch.clips["vanish"].sample(ch.skeleton, tt))
        pos, nrm = skin(ch.mesh, mats)
        pr, nr = skin_reference(ch.mesh, mats)
        assert np.isfinite(pos).all() and np.isfinite(nrm).all() and np.isfinite(nr).all()
        np.testing.assert_allclose(pos, pr, atol=1e-9)
    st = crowd(4, clip=2, spacing=2.0)
    images, reps, _ = render_frames(gl_ctx, [ch], st, look((1, 2, 8), (1, 1.5, 0)), np.linspace(0, 1, 9))
    assert np.isfinite(reps[0].joint_table).all() and np.isfinite(reps[0].clip_sphere).all()


def test_clip_with_180_degree_rotations_between_keys():
    """Keys 180 degrees apart (quaternion dot 0) and antipodal keys (q, -q: the
    same rotation): slerp stays unit, finite and continuous; no flips."""
    t = np.array([0.0, 1.0, 2.0, 3.0])
    q = np.array([[0, 0, 0, 1], [0, 0, 1, 0], [0, 0, 0, -1], [0, 0, -1, 0.0]])  # 0, 180, 360(= -q0), 540 deg
    ch = Channel(0, "rotation", t, q)
    ts = np.linspace(0, 3, 601)
    v = ch.sample(ts)
    assert np.isfinite(v).all()
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-9)
    # continuity: as rotations (sign-free), consecutive samples are close
    d = np.abs(np.sum(v[1:] * v[:-1], axis=1))
    assert d.min() > np.cos(np.radians(3.0))
    # antipodal keys: the shortest arc is no rotation at all
    anti = Channel(0, "rotation", np.array([0.0, 1.0]), np.array([[0, 0, 0.6, 0.8], [0, 0, -0.6, -0.8]]))
    va = anti.sample(np.linspace(0, 1, 51))
    np.testing.assert_allclose(np.abs(va @ np.array([0, 0, 0.6, 0.8])), 1.0, atol=1e-9)


def test_camera_inside_a_character_and_near_plane_through_the_crowd(gl_ctx):
    ch = tiny_skinned()
    st = crowd(16, spacing=0.6)
    cams = [look((0.0, 1.5, 0.0), (0.0, 1.5, 5.0), near=0.01),   # inside agent 0's column
            look((1.0, 1.0, -0.3), (1.0, 1.0, 3.0), near=1.0),   # near plane cuts through the crowd
            look((1.0, 10.0, 1.0), (1.0, 0.0, 1.0001), near=9.0)]
    for cam in cams:
        images, _, _ = render_frames(gl_ctx, [ch], st, cam, np.linspace(0, 1, FRAMES // 3))
        assert all(im.dtype == np.uint8 for im in images)


def test_camera_ten_thousand_km_away(gl_ctx):
    ch = tiny_skinned()
    st = crowd(9, spacing=2.0)
    cam = look((1e7, 2.0, 0.0), (0.0, 1.0, 0.0), near=1.0, far=2e7)
    px = cam.project(st.position, (96, 64))
    assert np.isfinite(px).all()
    images, _, sel = render_frames(gl_ctx, [ch], st, cam, np.linspace(0, 1, 4))
    dl = sel.select(st, cam, (96, 64))
    assert np.isfinite(dl.proj).all() and np.isfinite(dl.view).all()


def _capture(gl_ctx, ch, st, cam, size):
    from lod.full.mode import NoLodSelector
    from lod.full.reps import build_rep
    from render.renderer import Renderer

    rep = build_rep(ch, key="hc:far")
    sel = NoLodSelector([rep])
    with Renderer(size, ctx=gl_ctx, debug=True) as r:
        r.upload(rep)
        out = []
        for _ in range(2):  # two identical frames
            dl = sel.select(st, cam, size)
            data = np.concatenate([b.instance_data for b in dl.batches])
            pos, _ = r.capture(rep.key, data)
            r.draw(dl)
            out.append((pos.astype(np.float64), r.read_pixels().copy(), dl))
    return out


def _to_pixels(cam, rel, size):
    """Pixels of camera-relative positions (the camera at the origin)."""
    from lod.view import Camera

    c0 = Camera(np.zeros(3), cam.rotation, cam.fov_y, cam.near, cam.far)
    return c0.project(rel.reshape(-1, 3), size)


def test_crowd_a_million_metres_from_the_origin_renders_without_jitter(gl_ctx):
    ch = tiny_skinned()
    size = (128, 96)
    far_origin = np.array([1e6, 0.0, -1e6])
    near_st = crowd(9, spacing=1.5)
    far_st = crowd(9, spacing=1.5, origin=tuple(far_origin))
    for s in (near_st, far_st):
        s.anim_time[:] = 0.37
    cam_near = look((1.5, 2.5, 9.0), (1.5, 1.0, 1.5))
    cam_far = look(far_origin + (1.5, 2.5, 9.0), far_origin + (1.5, 1.0, 1.5))
    a = _capture(gl_ctx, ch, far_st, cam_far, size)
    b = _capture(gl_ctx, ch, near_st, cam_near, size)
    # two identical frames far away: identical projected vertices and images
    pa0, pa1 = _to_pixels(cam_far, a[0][0], size), _to_pixels(cam_far, a[1][0], size)
    assert np.abs(pa0 - pa1).max() <= 0.1
    assert np.array_equal(a[0][1], a[1][1])
    # and the same crowd at the origin: within 0.1 pixel, images nearly equal
    pb = _to_pixels(cam_near, b[0][0], size)
    assert np.abs(pa0 - pb).max() <= 0.1
    diff = np.abs(a[0][1].astype(int) - b[0][1].astype(int))
    assert (diff.max(axis=2) > 8).mean() < 0.002
    # the instance data are camera-relative: small numbers, not 1e6
    assert np.abs(a[0][2].batches[0].instance_data[:, [3, 7, 11]]).max() < 100


def _world(n, spacing, effects):
    from sim.world import World

    ch = tiny_skinned()
    st = crowd(n, spacing=spacing)
    rng = np.random.default_rng(5)
    st.velocity[:, [0, 2]] = rng.normal(0, 1, (n, 2))
    w = World(state=st, characters=[ch], seed=3)
    for name, cfg in effects:
        w.install(name, cfg)
    return w


def test_dt_of_one_second():
    max_speed = 2.0
    w = _world(200, 1.0, [("boids", {"max_speed": max_speed, "bounds": [-20.0, -20.0, 20.0, 20.0]}),
                          ("animation", {})])
    for _ in range(60):
        w.step(1.0)
        w.state.check_finite()
        sp = np.linalg.norm(w.state.velocity[:, [0, 2]], axis=1)
        assert sp.max() <= max_speed * (1 + 1e-6)
    assert np.abs(w.state.position[:, [0, 2]]).max() < 1e3


def test_hundred_thousand_agents_in_one_grid_cell():
    from sim.world import World

    n = 100_000
    st = crowd(n, spacing=0.0)
    st.position[:, 0] += np.random.default_rng(1).uniform(0, 0.5, n)
    w = World(state=st, characters=[tiny_skinned()], seed=1)
    w.install("boids", {"radius": 2.0, "max_speed": 2.0})
    for _ in range(2):
        w.step(1.0 / 30.0)
        w.state.check_finite()
    assert np.linalg.norm(w.state.velocity[:, [0, 2]], axis=1).max() <= 2.0 * (1 + 1e-6)


def test_keyframed_and_skinned_together_many_frames(gl_ctx):
    st = crowd(12, spacing=2.0)
    st.character[6:] = 1
    images, _, _ = render_frames(gl_ctx, [tiny_skinned(), tiny_keyframed()], st, look((3, 3, 12), (3, 1, 3)),
                                 np.linspace(0, 3, FRAMES))
    assert all(im.std() > 0 for im in images)


def test_engine_scene_with_dt_of_one_second_runs_finite(tmp_path):
    """The whole engine (boids, obstacles, animation, terrain follow, rendering) at dt = 1 s."""
    from crowd.engine import Engine
    from crowd.scene import load_scene

    scene = tmp_path / "dt1.toml"
    scene.write_text("""
name = "dt1"
seed = 2
dt = 1.0
frames = 30
effects = ["animation", { name = "boids", max_speed = 3.0, bounds = [-15.0, -15.0, 15.0, 15.0] },
           { name = "obstacles", circles = [{ center = [0.0, 0.0], radius = 2.0 }] }, "terrain_follow"]

[[characters]]
name = "walker"
generator = "humanoid"
triangles = 600

[[placement]]
kind = "random"
character = "walker"
count = 60
size = [20.0, 20.0]
speed = 2.0
heading = "random"

[terrain]
size = [40.0, 40.0]
origin = [-20.0, 0.0, -20.0]
resolution = 17
height_scale = 3.0

[camera]
position = [0.0, 15.0, 25.0]
target = [0.0, 0.0, 0.0]

[render]
size = [64, 48]
""")
    with Engine(load_scene(scene), quiet=True) as eng:
        res = eng.run(out_dir=tmp_path / "out")
        st = eng.world.state
        st.check_finite()
        assert np.linalg.norm(st.velocity[:, [0, 2]], axis=1).max() <= 3.0 * (1 + 1e-6)
        assert np.abs(st.position[:, [0, 2]]).max() < 40.0
    assert res.summary["frames"] == 30


def _degenerate_skinned():
    """The degenerate mesh (zero-area, sliver, duplicate, non-manifold, open,
    coincident vertices) skinned to tiny_skinned's skeleton and clips."""
    base = tiny_skinned("degenerate")
    p, t = _degenerate_mesh()
    p = np.vstack([p, p + [0, 1.2, 0], p + [0, 2.4, 0]]).astype(np.float32)
    t = np.vstack([t, t + 10, t + 20]).astype(np.uint32)
    j = np.zeros((30, 4), np.uint16)
    j[10:20, 0], j[20:, 0] = 1, 2
    w = np.zeros((30, 4), np.float32)
    w[:, 0] = 1.0
    base.mesh = Mesh(positions=p, indices=t, joints=j, weights=w,
                     colors=np.tile([0.3, 0.7, 0.4, 1.0], (30, 1)).astype(np.float32))
    return base


def _shrinking_sphere():
    p, idx = _sphere()
    kfs = [_kf(p * s + np.array([0, 1, 0], np.float32), idx) for s in (1.0, 0.4, 0.1)]
    ident = np.arange(len(p), dtype=np.int32)
    segs = [Segment(ident, ident, idx.copy()) for _ in range(3)]
    return KeyframedCharacter("ball", {"shrink": KeyframeAnimation("shrink", np.array([0.0, 0.5, 1.0]), kfs, segs,
                                                                   duration=1.5, loop=True)})


@pytest.mark.parametrize("mode", ["none", "triangles", "clusters", "points", "auto"])
def test_degenerate_assets_in_every_lod_mode(gl_ctx, mode, tmp_path, monkeypatch):
    """Degenerate meshes and a sphere shrinking to 1/100 of its area through
    each LOD mode's build and selection: finite representations and instance
    data (the debug renderer refuses NaN/Inf), for many frames."""
    from lod.modes import MODES, mode_module
    from render.renderer import Renderer

    if mode not in MODES:
        pytest.fail(f"LOD mode {mode!r} is not registered in lod/modes.py")
    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path))
    mod = mode_module(mode)
    params = {k: p.default for k, p in getattr(mod, "PARAMS", {}).items()}
    chars = [_degenerate_skinned(), _shrinking_sphere()]
    reps, sel = mod.build(chars, ["degenerate", "ball"], [30, 30], params)
    st = crowd(16, spacing=2.0)
    st.character[8:] = 1
    size = (96, 64)
    cams = [look((3, 3, 12), (3, 1, 3)),                          # overview
            look((0.0, 1.0, 0.0), (0.0, 1.0, 5.0), near=0.01),      # inside agent 0's bounds
            look((3.0, 1.0, 1.0), (3.0, 1.0, 9.0), near=2.0),       # near plane cutting through the crowd
            look((1e7, 2.0, 0.0), (0.0, 1.0, 0.0), near=1.0, far=2e7)]  # 10,000 km away
    with Renderer(size, ctx=gl_ctx, debug=True) as r:
        for rep in reps:
            r.upload(rep)
        for f, t in enumerate(np.linspace(0, 1.5, 16)):
            st.anim_time[:] = t
            dl = sel.select(st, cams[f % len(cams)], size)
            r.draw(dl)
            check_frame(r, dl)  # DrawList, instance buffer and captured vertex outputs finite


@pytest.mark.parametrize("mode", ["none", "triangles", "clusters", "points", "auto"])
def test_far_crowd_images_match_origin_in_every_lod_mode(gl_ctx, mode, tmp_path, monkeypatch):
    """A crowd 1e6 m from the origin draws the same image as at the origin,
    and two identical frames draw identical images (camera-relative data)."""
    from lod.modes import mode_module
    from render.renderer import Renderer

    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path))
    mod = mode_module(mode)
    params = {k: p.default for k, p in getattr(mod, "PARAMS", {}).items()}
    reps, sel = mod.build([tiny_skinned()], ["tiny"], [30], params)
    size = (128, 96)
    far = np.array([1e6, 0.0, -1e6])
    images = {}
    for name, o in (("origin", np.zeros(3)), ("far", far)):
        st = crowd(9, spacing=1.5, origin=tuple(o))
        st.anim_time[:] = 0.37
        cam = look(o + (1.5, 2.5, 9.0), o + (1.5, 1.0, 1.5))
        with Renderer(size, ctx=gl_ctx, debug=True) as r:
            for rep in reps:
                r.upload(rep)
            frames = []
            for _ in range(2):
                r.draw(sel.select(st, cam, size))
                frames.append(r.read_pixels().copy())
        assert np.array_equal(frames[0], frames[1]), name
        images[name] = frames[0]
    assert images["origin"].std() > 0
    diff = np.abs(images["far"].astype(int) - images["origin"].astype(int)).max(axis=2)
    assert (diff > 8).mean() < 0.002
