"""Point-hierarchy drawer (render/points/draw.py): compute-shader splats against the
GL_POINTS reference and against the triangle rendering, depth test with the
frame's triangles, splat footprints, and the mode end to end through the CLI."""
import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from lod.points import mode as pm
from lod.points import rep as pm_rep
from lod.full.mode import NoLodSelector
from lod.full.reps import build_static_rep
from lod.view import Camera
from render.renderer import Renderer
from sim.character import KeyframedCharacter
from sim.keyframes import Keyframe, KeyframeAnimation, Segment
from sim.mesh import Mesh
from sim.state import CrowdState
from tiny_characters import uv_sphere

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "crowd"))


def sphere_character(n_lat=60, n_lon=100, name="ball") -> KeyframedCharacter:
    """A UV sphere (radius 1 centred at y = 1) that swells by 20% and shifts
    its colour over one non-looping segment: a compact, dense keyframed
    character (about 12,000 triangles)."""
    nrm, idx = uv_sphere(n_lat, n_lon)
    col0 = np.tile([0.8, 0.3, 0.2, 1.0], (nrm.shape[0], 1)).astype(np.float32)
    col1 = np.tile([0.2, 0.5, 0.9, 1.0], (nrm.shape[0], 1)).astype(np.float32)
    k0 = Keyframe((nrm + [0, 1, 0]).astype(np.float32), nrm.astype(np.float32), col0, idx)
    k1 = Keyframe((1.2 * nrm + [0, 1, 0]).astype(np.float32), nrm.astype(np.float32), col1, idx)
    ident = np.arange(nrm.shape[0], dtype=np.int32)
    anim = KeyframeAnimation("swell", np.array([0.0, 1.0]), [k0, k1], [Segment(ident, ident, idx.copy())],
                             duration=1.0, loop=False)
    return KeyframedCharacter(name, {"swell": anim})


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    cache = pm_rep.HierarchyCache(tmp_path_factory.mktemp("cache"))
    reps, sel = pm.build([sphere_character()], ["ball"], [30], {"splat_size": 1}, cache=cache,
                         progress=lambda it, d: it)
    return reps[0], sel


@pytest.fixture(scope="module")
def renderer(gl_ctx, ball):
    r = Renderer((256, 192), ctx=gl_ctx)
    r.upload(ball[0])
    yield r
    r.release()


def _state(n=1, u=0.4):
    st = CrowdState.empty(n)
    st.anim_time[:] = u
    return st


def _mask(img, bg):
    return np.abs(img.astype(int) - np.asarray(bg, int)).sum(2) > 0


def _bg(r):
    return r.read_pixels()[0, 0]


def _render(r, dl, path="compute"):
    r.drawer("points").path = path
    r.draw(dl)
    return r.read_pixels()


def _iou(a, b):
    return (a & b).sum() / max(1, (a | b).sum())


#: camera far enough for points to be drawn, near enough for a 57-pixel-wide disc
FAR = Camera.look_at((0.0, 1.0, 10.0), (0.0, 1.0, 0.0), fov_y=40.0)
#: farther: points are most of what is drawn, a 20-pixel disc
FARTHER = Camera.look_at((0.0, 1.0, 28.0), (0.0, 1.0, 0.0), fov_y=40.0)


def test_points_at_splat_1_agree_with_the_triangle_silhouette(renderer, ball):
    rep, sel = ball
    ref = dataclasses.replace(rep.keyframed, key="none:ball")
    renderer.upload(ref)
    for cam, min_iou in ((FAR, 0.97), (FARTHER, 0.85)):
        dl = sel.select(_state(), cam, renderer.size)
        assert dl.stats["points"] > 3000
        pts = _render(renderer, dl)
        bg = pts[0, 0]
        tri = _render(renderer, NoLodSelector([ref]).select(_state(), cam, renderer.size))
        mp, mt = _mask(pts, bg), _mask(tri, bg)
        assert mt.sum() > 300
        # no holes: the points cover >= 97 % of the triangle silhouette
        assert (mp & mt).sum() / mt.sum() >= 0.97
        # a 1-pixel splat covers the pixel holding the point, so the silhouette
        # grows by about half a pixel: IoU >= 97 % at 57 px, lower at 20 px
        assert _iou(mp, mt) >= min_iou, _iou(mp, mt)
        both = mp & mt
        assert np.abs(pts[both].astype(float) - tri[both].astype(float)).mean() < 12.0
    assert sel.select(_state(), FARTHER, renderer.size).stats["points"] > \
        sel.select(_state(), FARTHER, renderer.size).stats["triangles"]


def test_compute_splat_and_gl_points_give_nearly_the_same_image(renderer, ball):
    _, sel = ball
    for splat in (1, 2, 3):
        sel.splat_size = splat
        renderer.drawer("points")._reps["points:ball"].splat = splat
        dl = sel.select(_state(u=0.8), FAR, renderer.size)
        a = _render(renderer, dl, "compute")
        b = _render(renderer, dl, "gl_points")
        bg = a[0, 0]
        ma, mb = _mask(a, bg), _mask(b, bg)
        assert _iou(ma, mb) > 0.99
        both = ma & mb
        assert np.abs(a[both].astype(float) - b[both].astype(float)).mean() < 3.0
    sel.splat_size = 1
    renderer.drawer("points")._reps["points:ball"].splat = 1


def _one_point_batch(rep, data):
    return pm_rep.PointsBatch(rep.key, 0, np.array([0], np.int32), data.astype(np.float32), points=1,
                          point_jobs=np.array([[0, 0, 1]], np.int64), tri_jobs=np.zeros((0, 3), np.int64))


@pytest.mark.parametrize("splat", [1, 2, 3])
@pytest.mark.parametrize("path", ["compute", "gl_points"])
def test_a_single_point_covers_a_square_of_splat_size(renderer, ball, splat, path):
    rep, sel = ball
    dl = sel.select(_state(), FAR, renderer.size)
    data = np.zeros((1, 16))
    data[0, :12] = [1, 0, 0, 0.013, 0, 1, 0, 0.021, 0, 0, 1, -7.0]
    dl.batches = [_one_point_batch(rep, data)]
    dl.options["splat_size"] = splat  # the drawer splats at the size the DrawList names
    renderer.drawer("points")._reps["points:ball"].splat = splat
    try:
        img = _render(renderer, dl, path)
    finally:
        renderer.drawer("points")._reps["points:ball"].splat = 1
    m = _mask(img, img[0, 0])
    ys, xs = np.nonzero(m)
    assert m.sum() == splat * splat
    assert xs.max() - xs.min() == splat - 1 and ys.max() - ys.min() == splat - 1


def test_points_are_depth_tested_against_the_frames_triangles(renderer, ball):
    rep, sel = ball
    wall = Mesh(positions=np.array([[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]], np.float32),
                indices=np.array([[0, 1, 2], [0, 2, 3]], np.uint32))
    srep = build_static_rep(wall, key="static:wall")
    renderer.upload(srep)
    nsel = NoLodSelector([], static_reps=[srep])
    dl = sel.select(_state(), FAR, renderer.size)
    empty = CrowdState.empty(0)
    ball_only = _render(renderer, dl)
    assert _mask(ball_only, ball_only[0, 0])[96, 128]
    for z, ball_wins in ((3.0, False), (-3.0, True)):  # wall between camera and ball, then behind it
        m = np.eye(4)
        m[2, 3] = z
        walls = nsel.select(empty, FAR, renderer.size, statics=[("static:wall", m)]).batches
        wall_only = _render(renderer, dataclasses.replace(dl, batches=list(walls)))
        both = _render(renderer, dataclasses.replace(dl, batches=list(walls) + list(dl.batches)))
        want = ball_only if ball_wins else wall_only
        np.testing.assert_array_equal(both[80:112, 112:144], want[80:112, 112:144])


def test_nothing_non_finite_and_camera_inside_the_bounds(renderer, ball):
    rep, sel = ball
    for h in rep.hierarchies:
        for k, v in h.__dict__.items():
            if isinstance(v, np.ndarray) and v.dtype.kind == "f":
                assert np.isfinite(v).all(), k
    inside = Camera.look_at((0.0, 1.0, 0.2), (0.0, 1.0, -1.0), fov_y=60.0)
    dl = sel.select(_state(), inside, renderer.size)
    assert dl.stats["triangles"] > 0
    img = _render(renderer, dl)
    assert img.shape == (192, 256, 3)
    keys = np.frombuffer(renderer.drawer("points")._depth.read(), np.uint32)
    filled = keys[keys != 0xFFFFFFFF].view(np.float32)
    assert np.isfinite(filled).all() and ((filled >= 0) & (filled <= 1)).all()


def test_crowd_run_with_points_mode_end_to_end(tmp_path, monkeypatch):
    import csv

    from crowd_testutil import run_cli, tiny_scene

    scene = tmp_path / "tiny.toml"
    scene.write_text(tiny_scene(replace={'mode = "none"': 'mode = "points"\nkeyframes = 2\nsplat_size = 2',
                                         "position = [1.0, 2.0, 7.0]": "position = [1.0, 2.0, 40.0]"}))
    monkeypatch.setenv(pm_rep.CACHE_ENV, str(tmp_path / "cache"))
    out = tmp_path / "out"
    res = run_cli("run", scene, "--out", out)
    assert res.returncode == 0, res.stderr[-2000:]
    rows = list(csv.DictReader(open(next(out.rglob("frames.csv")))))
    assert len(rows) == 3
    assert all(int(r["points"]) > 0 for r in rows)


def test_sample_packing_and_job_tables():
    from render.points.draw import expand_jobs, fold_box, job_table, pack_samples, sample_box, unpack_samples

    rng = np.random.default_rng(0)
    p0, p1 = rng.normal(size=(64, 3)) + 1e4, rng.normal(size=(64, 3)) + 1e4  # far from the origin
    n0 = rng.normal(size=(64, 3))
    n0 /= np.linalg.norm(n0, axis=1, keepdims=True)
    n0[:6] = [[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, -1, 0], [0.6, 0, -0.8], [0, 0, 0]]  # poles, edges, zero
    c0 = rng.uniform(size=(64, 4))
    lo, scale = sample_box(p0, p1)
    assert (lo <= np.minimum(p0, p1).min(axis=0)).all() and scale >= np.ptp(np.concatenate([p0, p1]), axis=0).max()
    p0[2, 1] = np.nan  # never reaches the GPU
    w = pack_samples(p0, p1, n0, n0, c0, c0, lo, scale)
    assert w.shape == (64, 8) and w.dtype == np.uint32
    d = unpack_samples(w, lo, scale)
    assert all(np.isfinite(v).all() for v in d.values())
    # positions within half a unorm16 step of the box
    ok = np.isfinite(p0).all(axis=1)
    assert np.abs(d["p0"][ok] - p0[ok]).max() <= scale / 131070 * 1.001
    assert np.abs(d["p1"] - p1).max() <= scale / 131070 * 1.001
    np.testing.assert_allclose(d["c0"], c0, atol=0.5 / 255 + 1e-9)
    # octahedral normals: unit, within 1e-4 rad; a zero normal decodes to +z
    cos = (d["n0"][:5] * n0[:5]).sum(axis=1)
    assert cos.min() > np.cos(1e-4) and np.isfinite(d["n0"]).all()
    assert (np.einsum("ij,ij->i", d["n0"][6:], n0[6:]) > np.cos(2e-4)).all()
    np.testing.assert_allclose(d["n0"][5], [0, 0, 1])
    # the folded instance rows map box coordinates to the same model-frame points as the rows do
    rows = rng.normal(size=(3, 16))
    f = fold_box(rows, lo, scale).astype(np.float64)
    q = (d["p1"] - lo) / scale
    for i in range(3):
        m = rows[:, 4 * i:4 * i + 4]
        want = d["p1"][:3] @ m[:, :3].T + m[:, 3]
        got = q[:3] @ f[:, 4 * i:4 * i + 3].T + f[:, 4 * i + 3]
        np.testing.assert_allclose(np.diag(got), np.diag(want), rtol=1e-4, atol=1e-2)
    b1 = pm_rep.PointsBatch("points:a", 1, np.arange(2, dtype=np.int32), np.zeros((2, 16), np.float32),
                        point_jobs=np.array([[0, 5, 3], [1, 0, 0], [1, 7, 2]]))
    b2 = pm_rep.PointsBatch("points:a", 0, np.arange(1, dtype=np.int32), np.zeros((1, 16), np.float32),
                        point_jobs=np.array([[0, 1, 4]]))
    jobs = job_table([b1, b2], "points:a", np.array([0, 100]), "point_jobs", {id(b1): 0, id(b2): 2})
    # empty jobs dropped; segment base added; instance rows offset; exclusive prefix
    np.testing.assert_array_equal(jobs, [[105, 3, 0, 0], [107, 2, 1, 3], [1, 4, 2, 5]])
    np.testing.assert_array_equal(expand_jobs(jobs), [[105, 0], [106, 0], [107, 0], [107, 1], [108, 1],
                                                      [1, 2], [2, 2], [3, 2], [4, 2]])


# ---------------------------------------------------------------------------- hierarchical instantiation (§3.6)
def _walker(radii=(0.3, 0.9, 0.3)):
    """Looping 3-keyframe walker (an ellipsoid 1.8 m tall that sways; as in
    tests/lod/points/test_points_instancing.py); ``radii`` its half-axes."""
    from sim.keyframes import Keyframe as K

    n_lat, n_lon = 12, 16
    th = np.linspace(0, np.pi, n_lat + 1)
    ph = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    T, P = np.meshgrid(th, ph, indexing="ij")
    nrm = np.stack([np.sin(T) * np.cos(P), np.cos(T), np.sin(T) * np.sin(P)], -1).reshape(-1, 3)
    idx = np.array([t for i in range(n_lat) for j in range(n_lon)
                    for t in ([(i * n_lon + j, i * n_lon + (j + 1) % n_lon, (i + 1) * n_lon + (j + 1) % n_lon)]
                              if i > 0 else []) + ([(i * n_lon + j, (i + 1) * n_lon + (j + 1) % n_lon,
                                                      (i + 1) * n_lon + j)] if i < n_lat - 1 else [])], np.uint32)
    base = nrm * list(radii) + [0, radii[1], 0]
    keys = []
    for sway, col in ((0.0, (0.8, 0.3, 0.2)), (0.35, (0.2, 0.6, 0.3)), (-0.35, (0.2, 0.3, 0.8))):
        p = base.copy()
        p[:, 0] += sway * (p[:, 1] / 1.8) ** 2
        keys.append(K(p.astype(np.float32), nrm.astype(np.float32),
                      np.tile([*col, 1.0], (len(p), 1)).astype(np.float32), idx))
    ident = np.arange(len(base), dtype=np.int32)
    anim = KeyframeAnimation("walk", np.array([0.0, 0.4, 0.8]), keys, [Segment(ident, ident, idx.copy())] * 3,
                             duration=1.2, loop=True)
    return KeyframedCharacter("walker", {"walk": anim})


def test_hierarchical_instantiation_renders_a_block_within_the_flat_instances_error(gl_ctx, tmp_path):
    """A 10 x 10 block drawn from its super-hierarchy (§3.6) against the same
    block drawn instance by instance (points) and as triangles."""
    from image_checks import silhouette_error
    from sim.instancing import Hierarchy, Instancing, parse_levels

    levels = parse_levels([{"layout": "grid", "nx": 10, "nz": 10, "spacing": [2.0, 2.0], "phase_step": 0.13}])
    h = Hierarchy(levels, character=0, clip=0, period=1.2)
    # coarse prefixes off: the super-hierarchy is compared with whole roots, as §3.6 has them (the flat
    # instances' coarse prefixes, lod/points/coarse.py, draw about as few points as the block's node)
    reps, sel = pm.build([_walker()], ["w"], [30], {"splat_size": 1, "coarse": False}, progress=False,
                         cache=pm_rep.HierarchyCache(tmp_path / "c"), instancing=Instancing([(0, h)]))
    flat = pm.PointsSelector(reps[:1], splat_size=1)
    ref = dataclasses.replace(reps[0].keyframed, key="none:w")
    r = Renderer((320, 240), ctx=gl_ctx)
    try:
        for rep in (*reps, ref):
            r.upload(rep)
        st = h.flatten(copy=True)
        st.anim_time[:] += 0.5
        checked = 0
        for splat, dist in ((1, 150.0), (2, 60.0), (2, 90.0), (3, 90.0)):
            sel.splat_size = flat.splat_size = splat
            cam = Camera.look_at((0.0, 0.5 * dist, dist), (0.0, 0.5, 0.0), fov_y=40.0, far=1000.0)
            dls = [s.select(st, cam, r.size) for s in (sel, flat, NoLodSelector([ref]))]
            assert dls[0].stats.get("super_nodes") == 1  # the whole block from its super-hierarchy
            assert dls[0].stats["points"] < 0.7 * dls[1].stats["points"]
            imgs = [_render(r, dl) for dl in dls]
            bg = imgs[2][0, 0]
            sup, fl, tri = (_mask(i, bg) for i in imgs)
            assert tri.sum() > 150
            # no holes: as much of the triangle silhouette covered as by the flat instances
            assert (sup & tri).sum() / tri.sum() >= min(0.97, (fl & tri).sum() / tri.sum() - 0.01)
            # silhouette distance to the triangles within a pixel of the flat instances'
            assert silhouette_error(sup, tri) <= silhouette_error(fl, tri) + 1.0
            assert silhouette_error(sup, fl) <= splat + 0.5
            both = sup & tri
            # mean colour difference (RGB sum) to the triangles on the shared pixels
            ce = np.abs(imgs[0][both].astype(float) - imgs[2][both].astype(float)).mean()
            bf = fl & tri
            cf = np.abs(imgs[1][bf].astype(float) - imgs[2][bf].astype(float)).mean()
            assert ce <= cf + 5.0  # colours (filtered over weighted sources) as close as the instances'
            checked += 1
        assert checked == 4
    finally:
        r.release()


def test_a_super_hierarchy_node_carries_the_mean_colour_of_the_agents_it_stands_for(gl_ctx, tmp_path):
    """Issue 43 (pre-filtered coarse nodes): a 10 x 10 block whose agents each wear red or blue (palette
    variation words, lod.variation) drawn from its super-hierarchy has the block's mean colour, as full detail
    has it, not one agent's colour (a node drawn with its first agent's word was all red or all blue)."""
    from sim.instancing import Hierarchy, Instancing, parse_levels
    from lod.variation import variation_words

    levels = parse_levels([{"layout": "grid", "nx": 10, "nz": 10, "spacing": [2.0, 2.0], "phase_step": 0.13}])
    h = Hierarchy(levels, character=0, clip=0, period=1.2)
    words = variation_words(5, np.arange(h.n_instances), palette=[(0.9, 0.1, 0.1), (0.1, 0.1, 0.9)])
    reds = int((words & 0xFF == round(0.9 * 255)).sum())
    assert 30 <= reds <= 70  # a mix of both colours (seed 5)
    reps, sel = pm.build([_walker()], ["w"], [30], {"splat_size": 1, "coarse": False}, progress=False,
                         cache=pm_rep.HierarchyCache(tmp_path / "c"), instancing=Instancing([(0, h)]),
                         variation=words)
    ref = dataclasses.replace(reps[0].keyframed, key="none:w")
    r = Renderer((320, 240), ctx=gl_ctx)
    try:
        r.tint_table = words
        for rep in (*reps, ref):
            r.upload(rep)
        st = h.flatten(copy=True)
        cam = Camera.look_at((0.0, 60.0, 120.0), (0.0, 0.5, 0.0), fov_y=40.0, far=1000.0)
        dl = sel.select(st, cam, r.size)
        assert dl.stats.get("super_nodes") == 1
        imgs = [_render(r, d) for d in (dl, NoLodSelector([ref]).select(st, cam, r.size))]
        bg = imgs[1][0, 0]
        means = []
        for img in imgs:
            m = _mask(img, bg)
            assert m.sum() > 200
            means.append(img[m].astype(float).mean(0))
        red_share = [mu[0] / (mu[0] + mu[2]) for mu in means]
        assert 0.3 < red_share[1] < 0.7
        assert abs(red_share[0] - red_share[1]) < 0.05, (means, red_share)
        chroma = [mu / mu.sum() for mu in means]
        assert np.abs(chroma[0] - chroma[1]).max() < 0.03, (means, chroma)
        # (brightness: the splats are fatter than the mesh, their extra pixels lit at grazing angles)
        assert 0.8 < means[0].sum() / means[1].sum() < 1.25, means
        # the node's draw gets no word of its own (render.tint.PREVARIED): its colours already carry them
        from render.tint import batch_words

        sup = [b for b in dl.batches if b.rep.startswith("points:super:")]
        assert sup and (batch_words(sup, words)[:, 0] == 0).all()
    finally:
        r.release()


@pytest.mark.parametrize("per_group", [3, 16])
def test_several_jobs_per_work_group_splat_the_same_image(renderer, ball, monkeypatch, per_group):
    import render.points.draw as rp

    _, sel = ball
    st = CrowdState.empty(7)  # several instances: a job count that is not a multiple of the group's jobs
    st.position[:, 0] = np.linspace(-6.0, 6.0, 7)
    st.position[:, 2] = np.linspace(0.0, -12.0, 7)
    st.anim_time[:] = np.linspace(0.1, 0.9, 7)
    dl = sel.select(st, FARTHER, renderer.size)
    jobs = sum(b.point_jobs.shape[0] for b in dl.batches if hasattr(b, "point_jobs"))
    assert jobs > per_group and jobs % per_group != 0
    monkeypatch.setattr(rp, "SPLAT_JOBS_PER_GROUP", 1)
    one = _render(renderer, dl)
    monkeypatch.setattr(rp, "SPLAT_JOBS_PER_GROUP", per_group)
    many = _render(renderer, dl)
    assert _mask(one, one[0, 0]).sum() > 500
    np.testing.assert_array_equal(one, many)


# ---------------------------------------------------------------------------- filled tiles: resolve and clear
@pytest.mark.parametrize("splat", [1, 2, 3])
def test_resolve_rects_hold_every_pixel_a_filled_anchor_reaches(splat):
    from render.points.draw import MARGIN, TILE
    from render.screen import resolve_rects

    rng = np.random.default_rng(splat)
    for w, h in ((64, 40), (61, 37), (8, 8), (9, 1)):
        sx, sy = w + MARGIN, h + MARGIN
        tx, ty = -(-sx // TILE), -(-sy // TILE)
        for trial in range(20):
            anchors = np.zeros((sy, sx), bool)
            k = rng.integers(0, 6)
            anchors[rng.integers(0, sy, k), rng.integers(0, sx, k)] = True
            if trial == 0:
                anchors[0, 0] = anchors[-1, -1] = True  # the border slots and the last one
            flags = np.zeros((ty * TILE, tx * TILE), bool)
            flags[:sy, :sx] = anchors
            flags = flags.reshape(ty, TILE, tx, TILE).any(axis=(1, 3))
            rects = resolve_rects(flags, (w, h), TILE, MARGIN, splat)
            cover = np.zeros((h, w), int)
            for x0, y0, x1, y1 in rects:
                assert 0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h
                cover[y0:y1, x0:x1] += 1
            assert cover.max(initial=0) <= 1  # no pixel resolved twice
            # every pixel a filled anchor's s x s footprint covers is inside a rectangle
            ys, xs = np.nonzero(anchors)
            for ay, ax in zip(ys - MARGIN, xs - MARGIN):
                for dy in range(splat):
                    for dx in range(splat):
                        px, py = ax + dx, ay + dy
                        if 0 <= px < w and 0 <= py < h:
                            assert cover[py, px] == 1
            if not anchors.any():
                assert rects.shape[0] == 0


def test_frames_after_a_dense_frame_keep_no_stale_splats(renderer, ball, monkeypatch):
    """The clear resets only the tiles the last frame filled: a sparse frame
    after a dense one must equal the sparse frame drawn first, with either
    clear (tile list or everything) and either resolve (rectangles or one
    full-screen triangle)."""
    import render.points.draw as rp

    _, sel = ball
    dense = CrowdState.empty(9)
    dense.position[:, 0] = np.linspace(-8.0, 8.0, 9)
    dense.anim_time[:] = 0.3
    sparse = _state(1, 0.7)
    sparse.position[0, 0] = 3.0
    dl_dense = sel.select(dense, FARTHER, renderer.size)
    dl_sparse = sel.select(sparse, FARTHER, renderer.size)
    assert dl_dense.stats["points"] > 3 * dl_sparse.stats["points"] > 0
    want = _render(renderer, dl_sparse)
    assert _mask(want, want[0, 0]).sum() > 50
    for clear_share, resolve_share in ((1.0, 1.0), (0.0, 0.0), (1.0, 0.0), (0.0, 1.0)):
        monkeypatch.setattr(rp, "FULL_CLEAR_SHARE", clear_share)
        monkeypatch.setattr(rp, "FULL_RESOLVE_SHARE", resolve_share)
        for _ in range(2):
            _render(renderer, dl_dense)
            np.testing.assert_array_equal(_render(renderer, dl_sparse), want)
    # a frame with no point at all, then the sparse one again
    none = CrowdState.empty(1)
    none.position[0, 0] = 500.0  # outside the view
    _render(renderer, sel.select(none, FARTHER, renderer.size))
    np.testing.assert_array_equal(_render(renderer, dl_sparse), want)


def test_two_reps_share_the_sample_buffer_and_a_replaced_upload(gl_ctx, ball, tmp_path):
    """Samples of several reps live in one buffer (uploads append; a rep
    uploaded again gets a new range): each rep still draws its own points."""
    cache = pm_rep.HierarchyCache(tmp_path)
    reps2, sel2 = pm.build([sphere_character(30, 50, name="ball2")], ["ball2"], [30], {"splat_size": 1},
                           cache=cache, progress=lambda it, d: it)
    rep1, sel1 = ball
    r = Renderer((256, 192), ctx=gl_ctx)
    try:
        r.upload(reps2[0])
        alone = _render(r, sel2.select(_state(), FARTHER, r.size))
        r.upload(rep1)
        r.upload(reps2[0])  # again: appended, its old range left unused
        for path in ("compute", "gl_points"):
            img = _render(r, sel2.select(_state(), FARTHER, r.size), path)
            m_alone, m = _mask(alone, alone[0, 0]), _mask(img, img[0, 0])
            assert m.sum() > 100 and _iou(m, m_alone) > 0.97
        # both reps in one frame: the union of their images
        st = _state()
        st.position[0, 0] = -2.5
        a = sel1.select(st, FARTHER, r.size)
        b = sel2.select(_state(), FARTHER, r.size)
        both = dataclasses.replace(a, batches=list(a.batches) + list(b.batches))
        img = _render(r, both)
        ia, ib = _render(r, a), _render(r, b)
        ma, mb, m = _mask(ia, ia[0, 0]), _mask(ib, ib[0, 0]), _mask(img, img[0, 0])
        assert _iou(m, ma | mb) > 0.97
    finally:
        r.release()


def test_indexed_triangle_jobs_give_every_jobs_triangles_in_order():
    from render.points.draw import expand_jobs, indexed_triangle_jobs

    rng = np.random.default_rng(5)
    corners = rng.integers(0, 40, size=(60, 3)).astype(np.uint32)
    jobs = np.array([[0, 5, 0], [3, 7, 1], [0, 5, 2], [50, 10, 0], [20, 1, 3]], np.int64)
    pre = np.concatenate([[0], np.cumsum(jobs[:-1, 1])])
    jobs = np.concatenate([jobs, pre[:, None]], axis=1).astype(np.uint32)
    cache = {}
    for _ in range(2):  # the second call from the cache
        items, index = indexed_triangle_jobs(jobs, corners, cache)
        per_tri = expand_jobs(jobs)  # (triangle, instance) per triangle, job order
        tri = items[index].reshape(-1, 3, 2)
        np.testing.assert_array_equal(tri[:, :, 0], corners[per_tri[:, 0]])
        np.testing.assert_array_equal(tri[:, :, 1], np.repeat(per_tri[:, 1:], 3, axis=1))
        # each job's vertices once: no (vertex, instance) pair twice within a job
        assert items.shape[0] == sum(np.unique(corners[f:f + c]).shape[0] for f, c in jobs[:, :2])
    assert len(cache) == 4
    e_items, e_index = indexed_triangle_jobs(np.zeros((0, 4), np.uint32), corners, cache)
    assert e_items.shape == (0, 2) and e_index.shape == (0,)


@pytest.mark.parametrize("blend", [True, False])
def test_points_tied_in_depth_splat_the_same_image_every_time(gl_ctx, tmp_path, blend):
    """Two spheres of different colours at the same place: every point of one ties in depth with a point of the
    other. The colour pass adds integer colour x weight sums (blend) or keeps the smallest packed colour
    (atomicMin, the nearest rule), so the image does not depend on the order llvmpipe's threads run in: five
    renderers, five identical images (found by scripts/frame_digests.py: grid in mode points drew 4 pixels
    differently run to run)."""
    red = sphere_character(40, 60, name="red")
    blue = dataclasses.replace(red, name="blue", animations={
        "swell": dataclasses.replace(red.animations["swell"], keyframes=[
            dataclasses.replace(k, colors=np.tile([0.1, 0.3, 0.95, 1.0], (k.colors.shape[0], 1)).astype(np.float32))
            for k in red.animations["swell"].keyframes])})
    cache = pm_rep.HierarchyCache(tmp_path / "c")
    builds = {names: pm.build([{"red": red, "blue": blue}[n] for n in names], list(names), [30, 30],
                              {"splat_size": 3}, cache=cache, progress=False)
              for names in (("red", "blue"), ("blue", "red"))}
    cam = Camera.look_at((0.0, 1.0, 40.0), (0.0, 1.0, 0.0), fov_y=25.0, far=100.0)
    images = []
    # which sphere is drawn first varies with the characters' order and the agents'
    for names, order in ((("red", "blue"), [0, 1]), (("blue", "red"), [0, 1]), (("red", "blue"), [1, 0]),
                         (("blue", "red"), [1, 0, 1, 0]), (("red", "blue"), [0, 1])):
        reps, sel = builds[names]
        st = CrowdState.empty(len(order))
        st.character[:] = order
        st.anim_time[:] = 0.3
        r = Renderer((160, 120), ctx=gl_ctx)
        try:
            for rep in reps:
                r.upload(rep)
            dl = sel.select(st, cam, r.size)
            assert dl.stats["points"] > 100 and dl.stats["triangles"] == 0  # splats only: coincident
            dl.options["splat_blend"] = 2.0 if blend else 0.0  # [lod] splat_blend
            images.append(_render(r, dl))  # triangles would z-fight by draw order, as GL's depth test does
        finally:
            r.release()
    for img in images[1:]:
        assert np.array_equal(img, images[0])
    bg = images[0][0, 0]
    covered = np.abs(images[0].astype(int) - bg.astype(int)).sum(-1) > 0
    assert covered.sum() > 80


def test_an_instanced_group_turned_by_90_degrees_keeps_its_mean_colour(gl_ctx, tmp_path):
    """Issue 43: every normal goes through the whole instance transform (Wand & Straßer §3.6). A 6 x 6 block
    drawn from its super-hierarchy under a light from straight above, turned by 90 degrees about the vertical
    with the camera turned alike, is the same picture: its mean colour within 1/255 on every channel (normals
    left in the node's frame would be lit as if the camera had not turned: the headlight term |n . v| changes)."""
    from lod.points.mode import build as points_build
    from render.world.light import make_light
    from sim.instancing import Hierarchy, Instancing, parse_levels

    levels = parse_levels([{"layout": "grid", "nx": 6, "nz": 6, "spacing": [2.0, 2.0], "phase_step": 0.13}])
    means = []
    for yaw in (0.0, 0.5 * np.pi):
        h = Hierarchy(levels, character=0, clip=0, period=1.2, yaw=yaw)
        # a slab (0.6 m wide, 0.1 m thick): its normals turn with it
        reps, sel = points_build([_walker((0.3, 0.9, 0.05))], ["w"], [30], {"splat_size": 2, "coarse": False},
                                 progress=False, cache=pm_rep.HierarchyCache(tmp_path / "c"),
                                 instancing=Instancing([(0, h)]))
        r = Renderer((320, 240), ctx=gl_ctx)
        try:
            r.lighting.light = make_light(direction=(0.0, 1.0, 0.0))
            for rep in reps:
                r.upload(rep)
            st = h.flatten(copy=True)
            c, s = np.cos(yaw), np.sin(yaw)
            eye = np.array([20.0, 20.0, 70.0])  # turned like the group (yaw about +y: x' = c x + s z, z' = -s x + c z)
            eye = np.array([c * eye[0] + s * eye[2], eye[1], -s * eye[0] + c * eye[2]])
            cam = Camera.look_at(eye, (0.0, 0.5, 0.0), fov_y=40.0, far=1000.0)
            dl = sel.select(st, cam, r.size)
            assert dl.stats.get("super_nodes") == 1
            img = _render(r, dl)
            m = _mask(img, img[0, 0])
            assert m.sum() > 300
            means.append(img[m].astype(float).mean(0))
        finally:
            r.release()
    assert np.abs(means[0] - means[1]).max() <= 1.0, means


def test_the_drawlist_names_the_splat_blend_and_zero_is_the_nearest_point(renderer, ball):
    """``[lod] splat_blend`` reaches the drawer through the DrawList: 0 draws what the drawer's nearest rule
    (``Drawer.blend = False``) draws; the default blend draws another picture of the same pixels."""
    rep, _ = ball
    sel = pm.PointsSelector([rep], splat_size=2, splat_blend=0.0)
    cam = Camera.look_at((0.0, 1.0, 9.0), (0.0, 1.0, 0.0), fov_y=40.0)
    dl = sel.select(_state(), cam, renderer.size)
    assert dl.options["splat_blend"] == 0.0
    nearest = _render(renderer, dl)
    d = renderer.drawer("points")
    del dl.options["splat_blend"]
    try:
        d.blend = False
        assert np.array_equal(_render(renderer, dl), nearest)
    finally:
        d.blend = True
    dl.options["splat_blend"] = 2.0
    blended = _render(renderer, dl)
    bg = _bg(renderer)
    assert np.array_equal(_mask(blended, bg), _mask(nearest, bg))  # the same pixels covered
    assert (np.abs(blended.astype(int) - nearest.astype(int)).sum(2) > 0).sum() > 20  # other colours


def test_every_filled_anchor_holds_a_weight_and_its_mean_is_a_colour(renderer, ball):
    """The blend's resolve divides by an anchor's weight: every anchor the depth pass filled holds its nearest
    point's weight (>= 1) and sums whose mean is a colour (each channel <= 255 x weight), near and far, three
    coincident agents tying in depth; empty anchors hold nothing."""
    rep, sel = ball
    d = renderer.drawer("points")
    checked = 0
    for eye in ((0.0, 1.0, 4.0), (0.0, 1.0, 9.0), (0.0, 30.0, 200.0)):
        dl = sel.select(_state(3), Camera.look_at(eye, (0.0, 1.0, 0.0), fov_y=60.0), renderer.size)
        dl.options["splat_blend"] = 2.0
        img = _render(renderer, dl)
        assert img.dtype == np.uint8 and d.last_counts["points"] > 0  # (a frame of no points splats nothing)
        keys = np.frombuffer(d._depth.read(), np.uint32)[:d._pixels]
        acc = np.frombuffer(d._color.read(), np.uint32)[:4 * d._pixels].reshape(-1, 4).astype(np.int64)
        filled = keys != 0xFFFFFFFF
        assert filled.any()
        checked += 1
        assert (acc[filled, 3] >= 1).all()
        assert (acc[filled, :3] <= 255 * acc[filled, 3:4]).all()
        assert (acc[~filled] == 0).all()
    assert checked == 3
