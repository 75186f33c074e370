"""The compute rasteriser (render/raster/) against a CPU reference (tests/fixtures/raster_reference.py) and
against the hardware path: coverage exact, depth within one unit of the key (a float32 ulp), shared edges
watertight, tiny, degenerate and screen-edge triangles, far from the origin, windows, non-finite input."""
import dataclasses

import numpy as np
import pytest

from lod.drawlist import DrawBatch, DrawList
from lod.full.reps import StaticRep
from lod.view import Camera
from render.raster import tables as tb
from render.renderer import Renderer
from raster_reference import EMPTY, keys, rasterise

SIZE = (160, 96)


def _psnr(a, b) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(255.0 ** 2 / mse)


def _camera():
    return Camera.look_at((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), fov_y=50.0, near=0.1, far=100.0)


def _rep(pos, tris, double_sided=True, key="soup"):
    pos = np.asarray(pos, np.float32)
    rng = np.random.default_rng(7)
    nrm = rng.normal(size=pos.shape).astype(np.float32)
    col = np.concatenate([rng.uniform(0.2, 1.0, (pos.shape[0], 3)), np.ones((pos.shape[0], 1))], 1).astype(np.float32)
    box = np.stack([pos.min(0), pos.max(0)]).astype(np.float32)
    c = box.mean(0)
    sphere = np.array([*c, float(np.linalg.norm(pos - c, axis=1).max())])
    return StaticRep(key, pos, nrm, col, np.asarray(tris, np.uint32).reshape(-1, 3), box, sphere,
                     double_sided=double_sided)


def _drawlist(rep, rows=None, size=SIZE):
    cam = _camera()
    if rows is None:
        rows = np.zeros((1, 16), np.float32)
        rows[0, [0, 5, 10]] = 1.0
    rows = np.asarray(rows, np.float32).reshape(-1, 16)
    b = DrawBatch(rep.key, 0, np.arange(rows.shape[0], dtype=np.int32), rows, triangles=rep.n_triangles)
    dl = DrawList(np.zeros(3), cam.view_matrix(), cam.projection(size[0] / size[1]), size, [b])
    if getattr(rep, "kind", None) == "skinned":  # the frame's pose table (exact poses), as the engine attaches it
        from lod.poses import PoseSharing

        ps = PoseSharing(rate=0.0)
        ps.register([rep])
        ps.assign(dl)
    return dl


def _gpu(ctx, rep, threshold=64.0, compute=True, dl=None):
    """(image, depth keys, ids, screen texels) of one frame drawn with the compute path on (or off)."""
    with Renderer(SIZE, ctx=ctx, debug=True) as r:
        r.upload(rep)
        r.raster_threshold = threshold
        r.compute_raster = compute
        r.raster.route_all = True
        dl = dl or _drawlist(rep)
        r.draw(dl)
        img = r.read_pixels().copy()
        if not compute:
            return img, None, None, None, dl
        w, h = SIZE
        depth = np.frombuffer(r.raster._depth.read(), np.uint32)[:w * h].reshape(h, w).copy()
        ids = np.frombuffer(r.raster._ids.read(), np.uint32)[:w * h].reshape(h, w).copy()
        screen = np.frombuffer(r.raster.screen_table.texture.read(), np.int32).reshape(-1, 4).copy()
        return img, depth, ids, screen, dl


def _reference(rep, screen, threshold=64.0):
    v = rep.positions.shape[0]
    s = screen[:v].astype(np.int64)
    z = s[:, 2].astype(np.int32).view(np.float32).astype(np.float64)
    return rasterise(s[:, :2].copy(), z, s[:, 3].copy(), np.asarray(rep.indices, np.int64),
                     not rep.double_sided, SIZE[0], SIZE[1], int(round(threshold * 256)))


def _soup(rng, n, spread=1.0, size=0.25, depth=(-9.0, -3.0)):
    """n random triangles in front of the camera: centres within the view (``spread`` 1 = to its edges)."""
    zc = rng.uniform(*depth, n)
    half = np.tan(np.radians(25.0)) * -zc
    cx = rng.uniform(-1, 1, n) * half * SIZE[0] / SIZE[1] * spread
    cy = rng.uniform(-1, 1, n) * half * spread
    ctr = np.stack([cx, cy, zc], 1)
    pos = (ctr[:, None, :] + rng.normal(scale=size, size=(n, 3, 3))).reshape(-1, 3)
    return pos, np.arange(3 * n).reshape(-1, 3)


def _both_paths(ctx, rep, dl):
    """(hardware image, compute image, the compute path's counts) of one frame, every copy routed to compute."""
    with Renderer(SIZE, ctx=ctx, debug=True) as r:
        r.upload(rep)
        r.compute_raster = False
        r.draw(dl)
        hw = r.read_pixels().copy()
        r.compute_raster = True
        r.raster.route_all = True
        r.raster_threshold = 64.0
        r.draw(dl)
        return hw, r.read_pixels().copy(), dict(r.raster.last_counts)


def _window_positions(rep, dl):
    """float64 fixed-point window positions of the rep's vertices (the vertex pass's rule, exactly)."""
    p = np.concatenate([np.asarray(rep.positions, np.float64), np.ones((rep.positions.shape[0], 1))], 1)
    clip = p @ (np.asarray(dl.proj, np.float64) @ np.asarray(dl.view, np.float64)).T
    ndc = clip[:, :3] / clip[:, 3:]
    win = (ndc[:, :2] * 0.5 + 0.5) * np.array(SIZE)
    return (win - 0.5) * 256.0


def _check_against_reference(rep, depth, ids, screen):
    ref_depth, owner, hits, aside = _reference(rep, screen)
    ref = keys(ref_depth)
    covered = depth != EMPTY
    np.testing.assert_array_equal(covered, ref != EMPTY)  # coverage exact
    diff = np.abs(depth[covered].astype(np.int64) - ref[covered].astype(np.int64))
    assert diff.max(initial=0) <= 1  # within one unit of the key: a float32 ulp of the window depth
    # the winner: the reference's, unless another triangle is within an ulp of its depth there
    got = ids[covered].astype(np.int64)
    exp = owner[covered]
    bad = got != exp
    if bad.any():
        s = screen[:rep.positions.shape[0]].astype(np.int64)
        z = s[:, 2].astype(np.int32).view(np.float32).astype(np.float64)
        ys, xs = np.nonzero(covered)
        for y, x, t in zip(ys[bad], xs[bad], got[bad]):
            a, b, c = np.asarray(rep.indices, np.int64)[t]
            (x0, y0), (x1, y1), (x2, y2) = s[a, :2], s[b, :2], s[c, :2]
            X, Y = 256 * x, 256 * y
            area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
            w1 = (x0 - x2) * (Y - y2) - (y0 - y2) * (X - x2)
            w2 = (x1 - x0) * (Y - y0) - (y1 - y0) * (X - x0)
            d = z[a] + (w1 * (z[b] - z[a]) + w2 * (z[c] - z[a])) / area
            assert abs(np.float32(d).view(np.uint32).astype(np.int64) - int(ref[y, x])) <= 1
    return hits, aside


@pytest.mark.parametrize("double_sided", [True, False])
def test_random_soup_matches_the_reference(gl_ctx, double_sided):
    """600 random triangles (a few pixels each, overlapping): the GPU's fixed-point vertices are the float64
    rule's to one unit; its coverage equals the reference rasteriser's exactly, every depth key is within one
    unit of the reference's float32 key, and every pixel's triangle is the reference's (or one within an ulp)."""
    rng = np.random.default_rng(1)
    pos, tris = _soup(rng, 600)
    rep = _rep(pos, tris, double_sided)
    img, depth, ids, screen, dl = _gpu(gl_ctx, rep)
    ref_xy = _window_positions(rep, dl)
    assert np.abs(screen[:pos.shape[0], :2] - ref_xy).max() <= 1.0
    hits, aside = _check_against_reference(rep, depth, ids, screen)
    assert (depth != EMPTY).sum() > 2000 and hits.max() > 2  # a real soup: many pixels, overlaps
    assert not aside.any()


def test_shared_edges_are_watertight(gl_ctx):
    """A jittered grid of 40 x 24 quads (every interior edge shared by two triangles, vertices shared by six;
    some edges through pixel centres): every pixel centre inside it is covered exactly once, as the reference
    says, drawn single- and double-sided."""
    nx, ny = 40, 24
    rng = np.random.default_rng(3)
    gx, gy = np.meshgrid(np.linspace(-2.2, 2.2, nx + 1), np.linspace(-1.3, 1.3, ny + 1))
    jit = rng.uniform(-0.02, 0.02, (2,) + gx.shape)
    jit[:, [0, -1], :] = 0.0
    jit[:, :, [0, -1]] = 0.0
    jit[:, ::3, ::3] = 0.0  # some vertices exactly on the regular lattice
    pos = np.stack([gx + jit[0], gy + jit[1], np.full(gx.shape, -4.0) + 0.1 * gx], -1).reshape(-1, 3)
    i = np.arange(nx * ny)
    q = (i // nx) * (nx + 1) + i % nx
    tris = np.concatenate([np.stack([q, q + 1, q + nx + 2], 1), np.stack([q, q + nx + 2, q + nx + 1], 1)])
    for ds in (False, True):
        rep = _rep(pos, tris, ds, key=f"grid{ds}")
        with Renderer(SIZE, ctx=gl_ctx, debug=True) as r:
            r.upload(rep)
            r.raster_threshold = 64.0
            r.raster.route_all = True
            dl = _drawlist(rep)
            from render.raster.hook import split

            _, _, work = split(r, dl.batches, dl)
            assert work, "the grid goes to the compute path"
            counts = r.raster.hit_counts(work, np.asarray(dl.proj, np.float64) @ np.asarray(dl.view, np.float64))
            screen = np.frombuffer(r.raster.screen_table.texture.read(), np.int32).reshape(-1, 4).copy()
        _, _, hits, aside = _reference(rep, screen)
        np.testing.assert_array_equal(counts, hits)
        assert counts.max() == 1 and (counts == 1).sum() > 0.4 * SIZE[0] * SIZE[1]
        ys, xs = np.nonzero(counts)
        inner = counts[ys.min() + 3:ys.max() - 2, xs.min() + 3:xs.max() - 2]
        assert (inner == 1).all()  # no crack inside the grid's outline
        assert not aside.any()


def test_tiny_and_degenerate_triangles(gl_ctx):
    """Sub-pixel triangles, needles, collinear and repeated-vertex (zero-area) triangles: coverage and depth
    as the reference; the repeated-vertex ones cover nothing; the image has no non-finite colour."""
    rng = np.random.default_rng(5)
    pos, tris = _soup(rng, 400, size=0.01)  # most below a pixel
    n = pos.shape[0]
    a = rng.uniform(-1, 1, (60, 3)) * [1.5, 0.8, 0] + [0, 0, -4]
    d = rng.normal(size=(60, 3)) * 0.3
    colinear = np.stack([a, a + d, a + 2.5 * d], 1).reshape(-1, 3)
    repeated = np.stack([a, a, a + d], 1).reshape(-1, 3)
    needle = np.stack([a, a + d, a + d + 1e-4], 1).reshape(-1, 3)
    pos = np.concatenate([pos, colinear, repeated, needle])
    tris = np.arange(pos.shape[0]).reshape(-1, 3)
    rep = _rep(pos, tris)
    img, depth, ids, screen, _ = _gpu(gl_ctx, rep)
    _check_against_reference(rep, depth, ids, screen)
    owners = set(ids[depth != EMPTY].tolist())
    repeated_first = n // 3 + 60  # a repeated vertex snaps alike: zero area (3-D collinear ones may snap to slivers)
    assert not owners & set(range(repeated_first, repeated_first + 60))
    assert np.isfinite(img).all()


def test_triangles_crossing_the_screen_edge(gl_ctx):
    """Triangles around the screen's border (partly outside, some wholly): coverage and depth as the
    reference, clipped to the screen; none set aside."""
    rng = np.random.default_rng(9)
    pos, tris = _soup(rng, 500, spread=1.15, size=0.3)
    rep = _rep(pos, tris)
    img, depth, ids, screen, _ = _gpu(gl_ctx, rep)
    _check_against_reference(rep, depth, ids, screen)
    edge = np.zeros(depth.shape, bool)
    edge[[0, -1], :] = True
    edge[:, [0, -1]] = True
    assert (depth[edge] != EMPTY).sum() > 20


def test_large_and_near_plane_triangles_go_to_the_hardware_path(gl_ctx):
    """Triangles wider than the threshold and one crossing the near plane are drawn by the hardware: the
    image equals the hardware path's (PSNR >= 45 dB) and the counts say how many went where."""
    rng = np.random.default_rng(11)
    pos, tris = _soup(rng, 200, size=0.05)
    big = np.array([[-1.0, -0.6, -5.0], [1.2, -0.5, -5.5], [0.0, 0.9, -4.5]])
    near = np.array([[-0.5, -0.3, -0.05], [0.6, -0.2, -3.0], [0.0, 0.4, -3.0]])
    pos = np.concatenate([pos, big, near])
    rep = _rep(pos, np.arange(pos.shape[0]).reshape(-1, 3))
    with Renderer(SIZE, ctx=gl_ctx, debug=True) as r:
        r.upload(rep)
        r.raster_threshold = 8.0
        dl = _drawlist(rep)
        r.compute_raster = False
        r.draw(dl)
        hw = r.read_pixels().copy()
        r.compute_raster = True
        r.raster.route_all = True  # its sphere reaches the near plane: the router would leave it to the hardware
        r.draw(dl)
        cs = r.read_pixels()
        c = r.raster.last_counts
    assert c["triangles"] == 202 and c["spilled"] >= 2 and c["rasterised"] == 202 - c["spilled"]
    assert dl.stats["raster_triangles"] == c["rasterised"]
    assert _psnr(hw, cs) >= 45.0


def test_windows_give_the_same_image(gl_ctx):
    """A frame cut into windows by a small injected storage-buffer limit and texture limit (each window its
    own passes, composed by the depth test) draws the image of the unwindowed frame."""
    rng = np.random.default_rng(13)
    pos, tris = _soup(rng, 300, size=0.08)
    rep = _rep(pos, tris)
    rows = np.zeros((6, 16), np.float32)
    rows[:, [0, 5, 10]] = 1.0
    rows[:, 3] = np.linspace(-0.6, 0.6, 6)
    rows[:, 11] = np.linspace(0.0, -1.0, 6)
    dl = _drawlist(rep, rows)
    with Renderer(SIZE, ctx=gl_ctx, debug=True) as r:
        r.upload(rep)
        r.raster_threshold = 64.0
        r.raster.route_all = True
        r.draw(dl)
        one = r.read_pixels().copy()
        assert r.raster.last_counts["windows"] == 1
        r.raster.ssbo_limit = 12 * 700  # two instances' triangles per window (three 4-byte spill lists)
        r.draw(dl)
        assert r.raster.last_counts["windows"] == 3
        assert (r.read_pixels() == one).all()
        r.raster.ssbo_limit, r.raster.texel_limit = None, 1000  # screen texels: one instance's 900 per window
        r.draw(dl)
        assert r.raster.last_counts["windows"] == 6
        assert (r.read_pixels() == one).all()
        r.raster.texel_limit = None
        r.raster.pixel_limit = 4 * SIZE[0] * SIZE[1] - 4  # the per-pixel buffers would not bind: hardware only
        r.draw(dl)
        assert dl.stats["raster_triangles"] == 0
        assert _psnr(r.read_pixels(), one) >= 45.0


def test_non_finite_instance_data_never_reach_the_gpu(gl_ctx):
    """Instance rows with NaN are refused (FloatingPointError) by the compute path itself; non-finite vertex
    values become 0 in its tables."""
    from render.raster.frame import Work

    rep = _rep(*_soup(np.random.default_rng(2), 10))
    with Renderer(SIZE, ctx=gl_ctx, debug=False) as r:
        r.upload(rep)
        m = r.raster.mesh(rep, False)
        rows = np.zeros((1, 16), np.float32)
        rows[0, [0, 5, 10]] = 1.0
        rows[0, 3] = np.nan
        with pytest.raises(FloatingPointError):
            r.raster.draw([Work(m, rows, np.zeros((1, 2), np.uint32), 0, rep.n_triangles)], np.eye(4))
    rec = tb.vertex_records([[np.nan, 1.0, np.inf]], [[0.0, 1.0, 0.0]], [[1.0, 1.0, 1.0, 1.0]])
    assert np.isfinite(rec.view(np.float32)).all() and rec[0, 0] == 0 and rec[0, 2] == 0


def test_far_from_the_origin(gl_ctx):
    """The soup placed 10^6 m from the origin, camera beside it (the drawlist camera-relative as the selectors
    make it, in float64 first): the compute path draws the image it draws at the origin."""
    rng = np.random.default_rng(17)
    pos, tris = _soup(rng, 300, size=0.08)
    rep = _rep(pos, tris)
    far = np.array([1.0e6, 2.0e5, -3.0e6])
    # camera-relative rows of an instance at `far` seen from a camera at `far` (what lod does in float64)
    rel = (far - far).astype(np.float32)
    rows = np.zeros((1, 16), np.float32)
    rows[0, [0, 5, 10]] = 1.0
    rows[0, [3, 7, 11]] = rel
    a = _gpu(gl_ctx, rep, dl=_drawlist(rep))[0]
    b = _gpu(gl_ctx, dataclasses.replace(rep, key="far"), dl=_drawlist(dataclasses.replace(rep, key="far"), rows))[0]
    assert (a == b).all() and a.std() > 0


def _row_of_copies(rep, k: int) -> np.ndarray:
    """Instance rows of ``k`` copies of ``rep`` side by side, at different times and the same time (frame
    coordinates 0, 3.5, 7.25, 3.5, 3.5, 11 past the clip's offset)."""
    rows = np.zeros((k, 16), np.float32)
    rows[:, [0, 5, 10]] = 0.25
    rows[:, 3] = np.linspace(-0.9, 0.9, k)
    rows[:, 7] = -0.4
    rows[:, 11] = -4.0
    rows[:, 12] = rep.clip_offset[0] + np.resize(np.array([0.0, 3.5, 7.25, 3.5, 3.5, 11.0]), k)
    return rows


def test_skinned_copies_with_morph_targets_match_the_hardware_path(gl_ctx):
    """A skinned character with morph targets (the pose pass morphs, then skins: targets.glsl, skinning.glsl),
    copies at different times and the same time, every copy routed to compute: the frame is the hardware
    path's within 45 dB, with poses shared or not."""
    from tiny_characters import tiny_morphed

    from lod.full.reps import build_rep

    rep = build_rep(tiny_morphed(), fps=30)
    assert rep.targets is not None
    k = 6
    rows = _row_of_copies(rep, k)
    dl = _drawlist(rep, rows)
    with Renderer(SIZE, ctx=gl_ctx, debug=True) as r:
        r.upload(rep)
        r.raster.route_all, r.raster_threshold = True, 64.0
        r.raster.share_poses = False
        r.draw(dl)
        alone = r.read_pixels().copy()
    hw, shared, counts = _both_paths(gl_ctx, rep, dl)
    assert counts["rasterised"] > 0
    assert hw.std() > 3
    assert _psnr(hw, shared) >= 45.0 and (shared == alone).all()


@pytest.mark.parametrize("cache_windows", [1, 3])
def test_posed_vertices_read_in_place_give_the_gathered_image(gl_ctx, monkeypatch, cache_windows):
    """Skinned copies of one mesh whose poses sit in one window of the pose cache are read in place by the vertex
    pass (the cache's layout is the posed table's, no gather: issue 44's none-exact cost); poses spread over several
    cache windows cut the raster's windows there, each read in place; the image is the one the gather into the
    rasteriser's own table gives, bit for bit."""
    from tiny_characters import tiny_morphed

    from lod.full.reps import build_rep
    from render.raster import frame as rf

    rep = build_rep(tiny_morphed(), fps=30)
    k = 6
    rows = _row_of_copies(rep, k)
    dl = _drawlist(rep, rows)
    images, used = {}, []
    orig = rf.Raster._in_place
    for how in ("in place", "gathered"):
        def spy(self, *a, _how=how):
            out = orig(self, *a) if _how == "in place" else None
            used.append((_how, out is not None))
            return out

        monkeypatch.setattr(rf.Raster, "_in_place", spy)
        with Renderer(SIZE, ctx=gl_ctx, debug=True) as r:
            r.upload(rep)
            r.raster.route_all, r.raster_threshold = True, 64.0
            r.raster.share_poses = False
            V = rep.positions.shape[0]
            r.poses.window_bytes = -(-k // cache_windows) * V * 32  # slots of 2 (3 windows) or all 6 per window
            r.draw(dl)
            images[how] = r.read_pixels().copy()
            assert len(r.poses._posed[next(iter(r.poses._posed))].windows) == cache_windows
            assert r.raster.last_counts["windows"] == cache_windows
    assert used.count(("in place", True)) == cache_windows and ("in place", False) not in used
    assert ("gathered", False) in used
    assert images["in place"].std() > 3 and (images["in place"] == images["gathered"]).all()


def test_keyframed_segments_match_the_hardware_path(gl_ctx):
    """Keyframed copies (Wand & Strasser segments: start and end records mixed by each copy's u) of two
    segments through the compute path: the frame is the hardware path's within 45 dB."""
    from tiny_characters import tiny_keyframed

    from lod.full.reps import build_rep

    rep = build_rep(tiny_keyframed())
    assert rep.kind == "keyframed" and rep.n_parts >= 2
    batches = []
    for part in (0, 1):
        k = 4
        rows = np.zeros((k, 16), np.float32)
        rows[:, [0, 5, 10]] = 0.3
        rows[:, 3] = np.linspace(-1.0, 1.0, k) + 0.25 * part
        rows[:, 7] = -0.6 + 0.5 * part
        rows[:, 11] = -5.0
        rows[:, 12] = np.linspace(0.0, 1.0, k)  # u
        batches.append(DrawBatch(rep.key, part, np.arange(k, dtype=np.int32) + 4 * part, rows))
    cam = _camera()
    dl = DrawList(np.zeros(3), cam.view_matrix(), cam.projection(SIZE[0] / SIZE[1]), SIZE, batches)
    hw, cs, counts = _both_paths(gl_ctx, rep, dl)
    assert counts["rasterised"] > 0
    assert hw.std() > 3 and _psnr(hw, cs) >= 45.0


def test_a_cluster_cut_is_routed_by_its_own_triangles():
    """VDR-AM cuts go to the compute path by the size of the triangles they draw (render/raster/hook.py): a
    copy drawn at its leaf clusters (small triangles) is taken, one drawn at the coarse root cluster (large
    triangles) stays on the hardware path at the same distance (routed by the full mesh's triangles, far crowds'
    coarse cuts went to the compute path, where their large triangles cost ~100x what the hardware does)."""
    from types import SimpleNamespace

    from lod.raster_route import compute_mask
    from render.raster.hook import cluster_extents, cut_extents

    rng = np.random.default_rng(3)
    small = rng.uniform(-1.0, 1.0, (40, 1, 3)) + rng.uniform(-0.01, 0.01, (40, 3, 3))  # 40 triangles ~2 cm
    big = rng.uniform(-1.0, 1.0, (4, 3, 3))  # 4 triangles ~1 m: the coarse level of the same surface
    pos = np.concatenate([small.reshape(-1, 3), big.reshape(-1, 3)])
    flat = np.arange(pos.shape[0], dtype=np.uint32)
    st = SimpleNamespace(hierarchy=SimpleNamespace(tri_start=np.array([0, 20, 40, 44, 44])), flat=flat)
    m = SimpleNamespace(rep=SimpleNamespace(positions=pos.astype(np.float32)))
    ext = cluster_extents(st, m)
    assert ext.shape == (4,) and ext[3] == 0.0 and max(ext[:2]) < 0.03 < 0.5 < ext[2]
    assert cluster_extents(st, m) is ext  # once per hierarchy
    offsets, clusters = np.array([0, 2, 3, 3]), np.array([0, 1, 2], np.int32)  # leaves, root, an empty cut
    cut = cut_extents(offsets, clusters, ext)
    assert cut[0] == max(ext[:2]) and cut[1] == ext[2] and cut[2] == 0.0
    rows = np.zeros((2, 16), np.float32)
    rows[:, [0, 5, 10]] = 1.0
    rows[:, 11] = -40.0  # 40 m in front of the camera
    proj = _camera().projection(SIZE[0] / SIZE[1])
    mask = compute_mask(rows, cut[:2], 1.8, np.zeros(3), proj, SIZE[1], 2.0, 0.1)
    assert mask.tolist() == [True, False]


def test_a_rep_replaced_every_frame_reuses_its_rows(gl_ctx):
    """A representation uploaded again under its key each frame (the view-dependent terrain) draws the new
    mesh, like a fresh renderer does, and the shared tables stay bounded: a replacement reuses its
    predecessor's rows when it fits and dead rows are compacted away (each frame used to append its mesh)."""
    rng = np.random.default_rng(5)
    other = _rep(*_soup(np.random.default_rng(9), 40, size=0.05), key="other")
    with Renderer(SIZE, ctx=gl_ctx, debug=True) as r:
        r.upload(other)
        r.compute_raster = True
        r.raster.route_all = True
        r.raster_threshold = 64.0
        sizes = []
        for frame in range(12):
            n = int(rng.integers(30, 120))  # the mesh grows and shrinks
            rep = _rep(*_soup(rng, n, size=0.05), key="soup")
            r.upload(rep)
            dl = _drawlist(rep)
            dl.batches.append(_drawlist(other).batches[0])
            r.draw(dl)
            got = r.read_pixels().copy()
            sizes.append(r.raster._tris.shape[0])
            with Renderer(SIZE, ctx=gl_ctx, debug=True) as fresh:
                fresh.upload(other)
                fresh.upload(rep)
                fresh.raster.route_all = True
                fresh.raster_threshold = 64.0
                fresh.draw(dl)
                assert np.array_equal(got, fresh.read_pixels())
        live = 40 + 120
        assert max(sizes) <= 2 * 1.25 * live + 40  # bounded by the live meshes, not by the frames drawn
        assert r.raster.last_counts["triangles"] == 40 + n
