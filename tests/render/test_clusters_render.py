"""Rendering VDR-AM cluster cuts (render/clusters/draw.py): equality with the full mesh at
PoE 0, no cracks, screen-space error bounded by PoE, and the CPU command kernels."""
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import ndimage

from lod.clusters import cut as cluster_cut
from lod.clusters import mode as clusters_mode
from lod.full import mode as nolod
from lod.view import Camera
from render.clusters import draw as rc
from render.renderer import Renderer
from sim.procedural import humanoid, quadruped

from image_checks import silhouette_error  # tests/fixtures (on sys.path via tests/render/conftest.py)

SIZE = (320, 240)
BG = (0.1, 0.1, 0.12)


@pytest.fixture(scope="module")
def scene(gl_ctx):
    c = humanoid(2500, 0)
    reps, sel = clusters_mode.build([c], ["h"], [30], {"poe": 0.0}, cache=False)
    full, fsel = nolod.build([c], ["h"], [30], {})
    r = Renderer(SIZE, ctx=gl_ctx)
    for rep in [*reps, *full]:
        r.upload(rep)
    yield SimpleNamespace(c=c, reps=reps, sel=sel, full=full, fsel=fsel, r=r)
    r.release()


def _state(pos, heading, t, clip=None):
    n = len(pos)
    return SimpleNamespace(n=n, character=np.zeros(n, np.int64),
                           clip=np.zeros(n, np.int64) if clip is None else np.asarray(clip, np.int64),
                           anim_time=np.asarray(t, float), position=np.asarray(pos, float), scale=np.ones(n),
                           heading=np.asarray(heading, float))


def _render(sc, selector, state, cam, poe=None, strategy="indices", compute=True):
    """The frame; ``compute`` False: every triangle through the hardware path (the drawer's own commands,
    which the compute rasteriser would otherwise take for these small instances, render/raster/)."""
    if poe is not None:
        selector.poe = poe
    sc.r.drawer("clusters").strategy = strategy
    dl = selector.select(state, cam, SIZE)
    sc.r.compute_raster = compute
    try:
        sc.r.draw(dl, background=BG)
    finally:
        sc.r.compute_raster = True
    return sc.r.read_pixels(), dl


def _mask(img):
    bg = np.round(np.asarray(BG) * 255).astype(int)
    return np.abs(img.astype(int) - bg).max(axis=2) > 2


CROWD = ([[0, 0, 0], [1.2, 0, -1.5], [-1.0, 0, 0.8]], [0.0, 1.0, 2.5], [0.1, 0.45, 0.8], [0, 1, 0])


@pytest.mark.parametrize("strategy", rc.STRATEGIES)
def test_poe_zero_renders_the_full_mesh(scene, strategy):
    st = _state(*CROWD)
    cam = Camera.look_at((0, 1.2, 5.0), (0, 0.9, 0))
    ref, _ = _render(scene, scene.fsel, st, cam)
    img, dl = _render(scene, scene.sel, st, cam, poe=0.0, strategy=strategy)
    assert _mask(ref).sum() > 2000
    assert dl.stats["triangles"] == 3 * scene.c.mesh.n_triangles
    assert np.array_equal(img, ref)


def test_coarse_cut_changes_the_image_and_draws_fewer_triangles(scene):
    """The comparison above can fail: a coarse cut differs from the full mesh."""
    st = _state(*CROWD)
    cam = Camera.look_at((0, 1.2, 5.0), (0, 0.9, 0))
    ref, _ = _render(scene, scene.fsel, st, cam)
    img, dl = _render(scene, scene.sel, st, cam, poe=40.0)
    assert dl.stats["triangles"] < 3 * scene.c.mesh.n_triangles
    assert not np.array_equal(img, ref)


#: supersampling of the silhouette measurements: the cut is chosen for SIZE,
#: the images are rendered at SS x SIZE, so sub-pixel features are resolved
SS = 4
POSES = [(0.0, 0.05, 0), (2.4, 0.75, 1), (-0.8, 0.3, 1)]
DISTANCES = (3.0, 7.0, 14.0)


@pytest.fixture(scope="module")
def hires(scene, gl_ctx):
    r = Renderer((SIZE[0] * SS, SIZE[1] * SS), ctx=gl_ctx)
    for rep in [*scene.reps, *scene.full]:
        r.upload(rep)
    yield r
    r.release()


def _hires(r, dl):
    """Fill coverage, fill-or-edge coverage (slivers thinner than a pixel still
    count: wireframe pass) and linear depth of a DrawList rendered by ``r``."""
    r.draw(dl, background=BG)
    fill = _mask(r.read_pixels())
    w, h = r.size
    depth = np.frombuffer(r.fbo.read(components=1, attachment=-1, dtype="f4"), np.float32).reshape(h, w)[::-1]
    r.ctx.wireframe = True
    try:
        r.draw(dl, background=BG)
    finally:
        r.ctx.wireframe = False
    return fill, fill | _mask(r.read_pixels()), depth


def _crack_pixels(full_fill, full_depth, cut_fill, cam, band_px):
    """Background pixels of the cut inside the full silhouette, farther than
    ``band_px`` from the full mesh's outline and its occluding contours (depth
    jumps above 5 cm), where a simplified silhouette may legitimately move."""
    n, f = cam.near, cam.far
    z = np.where(full_fill, 2 * n * f / (f + n - (2 * full_depth.astype(np.float64) - 1) * (f - n)), 1e9)
    edge = ~full_fill
    for ax in (0, 1):
        j = np.abs(np.diff(z, axis=ax)) > 0.05
        sl0 = (slice(1, None), slice(None)) if ax == 0 else (slice(None), slice(1, None))
        sl1 = (slice(None, -1), slice(None)) if ax == 0 else (slice(None), slice(None, -1))
        edge[sl0] |= j
        edge[sl1] |= j
    band = ndimage.binary_dilation(edge, iterations=int(band_px))
    return full_fill & ~cut_fill & ~band


def _pose_cases():
    for heading, t, clip in POSES:
        for dist in DISTANCES:
            yield (_state([[0, 0, 0]], [heading], [t], [clip]),
                   Camera.look_at((0, 1.0, dist), (0, 0.9, 0), fov_y=40.0), (heading, dist))


@pytest.mark.parametrize("poe", [0.5, 1.0, 2.0])
def test_no_cracks_and_screen_space_error_within_poe(scene, hires, poe):
    """Closed humanoid, several poses and distances: (1) no background pixel
    inside the full silhouette away from its outline and occluding contours
    (cracks); (2) the silhouette distance between cut and full mesh, measured
    at 4x supersampling with sub-pixel slivers counted, stays <= PoE plus one
    supersampled pixel of rasterisation."""
    worst = 0.0
    refined = 0
    for st, cam, where in _pose_cases():
        ref_fill, ref_cov, ref_depth = _hires(hires, scene.fsel.select(st, cam, SIZE))
        scene.sel.poe = poe
        dl = scene.sel.select(st, cam, SIZE)
        refined += dl.stats["triangles"] < scene.c.mesh.n_triangles
        fill, cov, _ = _hires(hires, dl)
        cracks = _crack_pixels(ref_fill, ref_depth, fill, cam, np.ceil(SS * poe) + 2)
        assert not cracks.any(), f"{cracks.sum()} crack pixels at poe={poe}, (heading, distance)={where}"
        worst = max(worst, silhouette_error(ref_cov, cov) / SS)
    assert refined >= 3  # the cuts really are simplified
    assert worst <= poe + 1.0 / SS, worst


def test_crack_and_error_measures_can_fail(scene, hires):
    """A missing cluster is found as a crack; a coarse cut exceeds a small PoE."""
    st, cam, _ = next(_pose_cases())
    ref_fill, ref_cov, ref_depth = _hires(hires, scene.fsel.select(st, cam, SIZE))
    scene.sel.poe = 0.0
    dl = scene.sel.select(st, cam, SIZE)
    b = dl.batches[0]
    h = scene.reps[0].hierarchy
    tc = np.diff(h.tri_start)[b.clusters]
    drop = int(np.argmax(tc))  # drop the largest leaf: a hole in the surface
    keep = np.delete(b.clusters, drop)
    b.clusters, b.offsets = keep, np.array([0, keep.size], np.int64)
    fill, _, _ = _hires(hires, dl)
    assert _crack_pixels(ref_fill, ref_depth, fill, cam, SS + 2).any()
    scene.sel.poe = 60.0
    _, cov, _ = _hires(hires, scene.sel.select(st, cam, SIZE))
    assert silhouette_error(ref_cov, cov) / SS > 2.0


def test_strategies_render_the_same_image(scene):
    st = _state(*CROWD)
    cam = Camera.look_at((0, 1.2, 9.0), (0, 0.9, 0))
    a, _ = _render(scene, scene.sel, st, cam, poe=1.0, strategy="indices", compute=False)
    sa = dict(scene.r.drawer("clusters").last_stats)
    b, _ = _render(scene, scene.sel, st, cam, poe=1.0, strategy="ranges", compute=False)
    sb = dict(scene.r.drawer("clusters").last_stats)
    assert np.array_equal(a, b)
    assert sa["triangles"] == sb["triangles"] and sa["draws"] == sb["draws"] == 1
    assert sb["index_bytes"] == 0 and sa["index_bytes"] > 0


def test_identical_cuts_share_one_command(scene):
    # four instances side by side at the same distance and pose: one distinct cut
    st = _state([[x, 0, 0] for x in (-1.5, -0.5, 0.5, 1.5)], [0.0] * 4, [0.3] * 4)
    cam = Camera.look_at((0, 30.0, 0.01), (0, 0, 0))  # straight above: equal distances
    _render(scene, scene.sel, st, cam, poe=1.0, compute=False)
    s = scene.r.drawer("clusters").last_stats
    assert s["instances"] == 4 and s["draws"] == 1
    assert s["groups"] <= 2 and s["commands"] == s["groups"]


def test_command_kernels_match_numpy_references(scene):
    h = scene.reps[0].hierarchy
    rng = np.random.default_rng(3)
    M = np.tile(np.eye(4)[:3], (40, 1, 1))
    M[:, :, 3] = rng.uniform(-20, 20, (40, 3))
    offsets, clusters = cluster_cut.cut(h, M, np.zeros(3), 400.0, 1.0)
    order, counts, first = rc.group_cuts(offsets, clusters)
    assert counts.sum() == 40 and np.all(order[np.cumsum(counts) - counts] >= 0)
    # groups are made of identical cuts
    gid = np.repeat(np.arange(counts.shape[0]), counts)
    for i, g in zip(order.tolist(), gid.tolist()):
        f = first[g]
        assert np.array_equal(clusters[offsets[i]:offsets[i + 1]], clusters[offsets[f]:offsets[f + 1]])
    sub = np.array([5, 0, 39, 5], np.int64)
    so, sc = rc._sub_csr(offsets, clusters, sub)
    assert np.array_equal(sc, np.concatenate([clusters[offsets[i]:offsets[i + 1]] for i in sub]))
    assert np.array_equal(np.diff(so), offsets[sub + 1] - offsets[sub])
    flat = np.asarray(h.indices).reshape(-1)
    a, fa = rc.gather(flat, h.tri_start, offsets, clusters)
    b, fb = rc.gather_numpy(flat, h.tri_start, offsets, clusters)
    assert np.array_equal(a, b) and np.array_equal(fa, fb)
    base = np.arange(40, dtype=np.int64)
    ones = np.ones(40, np.int64)
    ca = rc.range_commands(h.tri_start, offsets, clusters, ones, base)
    cb = rc.range_commands_numpy(h.tri_start, offsets, clusters, ones, base)
    assert np.array_equal(ca, cb)
    # the commands cover exactly the cut triangles
    assert int(ca[:, 0].sum()) == 3 * int(cluster_cut.cut_triangle_count(h, offsets, clusters).sum())
    # a PoE-0 cut (all leaves, in order) is one run
    leaves = np.arange(h.n_leaves, dtype=np.int32)
    one = rc.range_commands(h.tri_start, np.array([0, h.n_leaves]), leaves, np.array([1]), np.array([0]))
    assert one.shape[0] == 1 and one[0, 0] == 3 * h.n_triangles


def test_empty_inputs():
    o, c, f = rc.group_cuts(np.zeros(1, np.int64), np.zeros(0, np.int32))
    assert o.size == c.size == f.size == 0
    ts = np.array([0, 2], np.int64)
    out, first = rc.gather(np.arange(6, dtype=np.uint32), ts, np.zeros(1, np.int64), np.zeros(0, np.int32))
    assert out.size == 0 and first.tolist() == [0]
    assert rc.range_commands(ts, np.zeros(1, np.int64), np.zeros(0, np.int32), np.zeros(0), np.zeros(0)).shape == (0, 5)
    with pytest.raises(ValueError, match="strategy"):
        rc.Drawer(SimpleNamespace(ctx=None), strategy="bogus")


def test_plain_batch_of_a_clusters_rep_draws_full_detail(scene):
    from lod.drawlist import DrawBatch, DrawList

    st = _state(*CROWD)
    cam = Camera.look_at((0, 1.2, 5.0), (0, 0.9, 0))
    ref, _ = _render(scene, scene.sel, st, cam, poe=0.0)
    dl = scene.sel.select(st, cam, SIZE)
    dl2 = DrawList(dl.origin, dl.view, dl.proj, dl.size,
                   [DrawBatch(b.rep, b.part, b.instance_ids, b.instance_data) for b in dl.batches])
    scene.r.draw(dl2, background=BG)
    assert np.array_equal(scene.r.read_pixels(), ref)


@pytest.fixture()
def occlusion_pair(scene, gl_ctx):
    """Two renderers of the scene's reps, with and without occlusion culling (§5.2)."""
    from dataclasses import replace

    with_oc, without = Renderer(SIZE, ctx=gl_ctx), Renderer(SIZE, ctx=gl_ctx)
    # occlusion-culled items stay on the hardware path (render/raster/hook.py split_clusters): compare like with like
    with_oc.compute_raster = without.compute_raster = False
    try:
        for rep in scene.reps:
            with_oc.upload(replace(rep, occlusion=True, occlusion_every=3))
            without.upload(rep)
        yield with_oc, without
    finally:
        with_oc.release()
        without.release()


def _occluded_crowd(seed, n_back):
    """A front row close to the camera hiding a crowd behind it (partly: gaps between legs and arms)."""
    front = [[x, 0, 0] for x in np.linspace(-1.6, 1.6, 9)]
    rng = np.random.default_rng(seed)
    back = np.column_stack([rng.uniform(-3, 3, n_back), np.zeros(n_back), rng.uniform(-25, -4, n_back)])
    pos = np.vstack([front, back])
    n = pos.shape[0]
    return _state(pos, rng.uniform(-0.3, 0.3, n), rng.uniform(0, 1, n), np.arange(n) % 2)


def test_occlusion_culling_never_removes_a_visible_cluster(scene, occlusion_pair):
    """§5.2: images equal with and without occlusion culling over frames that
    rebuild the visible set and frames that reuse it, while queries do cull."""
    with_oc, without = occlusion_pair
    st = _occluded_crowd(5, 40)
    scene.sel.poe = 1.0
    occluded = 0
    for frame in range(7):
        cam = Camera.look_at((0.05 * frame, 1.1, 1.6), (0, 1.0, -5.0), fov_y=45.0)
        dl = scene.sel.select(st, cam, SIZE)
        with_oc.draw(dl, background=BG)
        without.draw(dl, background=BG)
        s = with_oc.drawer("clusters").last_stats
        occluded += s["occluded"]
        assert s["instances"] + s["occluded"] == dl.stats["instances"]
        assert np.array_equal(with_oc.read_pixels(), without.read_pixels()), f"frame {frame}"
        st.anim_time = st.anim_time + 0.1
    assert occluded > 0
    assert with_oc.drawer("clusters").frame == 7


def test_occlusion_culling_with_geomorphed_cuts(scene, occlusion_pair):
    """Keyframed selection (lod.temporal.selection) geomorphs the cuts of a crowd the camera
    approaches; with occlusion culling the images equal those without, frame by frame."""
    from lod.temporal.selection import KeyframedSelector

    with_oc, without = occlusion_pair
    st = _occluded_crowd(6, 30)
    scene.sel.poe = 1.0
    sel = KeyframedSelector(scene.sel, n=3, mode="current")
    morph_rows = occluded = 0
    for frame in range(9):
        cam = Camera.look_at((0.0, 1.1, 9.0 - frame), (0, 1.0, -5.0), fov_y=45.0)
        dl = sel.select(st, cam, SIZE)
        with_oc.draw(dl, background=BG)
        without.draw(dl, background=BG)
        morph_rows += without.drawer("clusters").last_stats["morph_rows"]
        occluded += with_oc.drawer("clusters").last_stats["occluded"]
        assert np.array_equal(with_oc.read_pixels(), without.read_pixels()), f"frame {frame}"
        st.anim_time = st.anim_time + 0.05
    assert morph_rows > 0 and occluded > 0


# ---------------------------------------------------------------------------- rendered (filled) silhouettes
#: the 8,000-triangle procedural walker of scripts/bench_auto.md ("Image error"), seen as in
#: tests/lod/auto/test_auto_mode.py: camera at (0, 1, 3) looking down -z at one instance at depth z
WALKER_TRIANGLES = 8000
WALKER_DEPTHS = (-10.0, -25.0, -60.0)
WALKER_HEADINGS = (1.2, 2.0)
WALKER_TIMES = 5  # per clip, spread over the whole clip (not only the representative poses)


@pytest.fixture(scope="module", params=[("humanoid", 100), ("humanoid", 1000), ("quadruped", 2000)],
                ids=["humanoid-s100", "humanoid-s1000", "quadruped-s2000"])
def walker(gl_ctx, request):
    """The walker (or the stampede's quadruped) with leaves of the default 100 triangles and of 1,000-2,000
    (``[lod] leaf_triangles``, the leaf size scripts/bench_clusters.md measures stampede with)."""
    kind, leaf = request.param
    c = humanoid(WALKER_TRIANGLES, 0) if kind == "humanoid" else quadruped(WALKER_TRIANGLES, 101)
    reps, sel = clusters_mode.build([c], ["h"], [30], {"poe": 0.0, "leaf_triangles": leaf}, cache=False,
                                    progress=False)
    full, fsel = nolod.build([c], ["h"], [30], {})
    r = Renderer((SIZE[0] * SS, SIZE[1] * SS), ctx=gl_ctx)
    for rep in [*reps, *full]:
        r.upload(rep)
    cases = []
    for clip, name in enumerate(c.clips):
        dur = c.clip(name).duration
        for t in np.arange(WALKER_TIMES) * (dur / WALKER_TIMES) + 0.04:
            for heading in WALKER_HEADINGS:
                for z in WALKER_DEPTHS:
                    st = _state([[0.0, 0.0, z]], [heading], [t], [clip])
                    cam = Camera.look_at((0, 1.0, 3.0), (0, 0.9, z))
                    r.draw(fsel.select(st, cam, SIZE), background=BG)
                    cases.append((st, cam, _mask(r.read_pixels()), (clip, round(float(t), 3), heading, z)))
    yield SimpleNamespace(c=c, sel=sel, r=r, cases=cases)
    r.release()


@pytest.mark.parametrize("poe", [0.5, 1.0, 2.0])
def test_filled_silhouette_of_the_walker_within_poe(walker, poe):
    """The acceptance point on the procedural humanoid (8,000 triangles), walking and running, at
    several clip times, headings and distances: the largest distance between the FILLED
    silhouettes of the cut and of the full mesh (4x supersampled, no wireframe pass, i.e. what
    the image shows) stays <= PoE plus one supersampled pixel, diagonally (both images are
    rasterised without the wireframe pass, so a sub-sample sliver may drop one supersampled pixel
    in either axis; measured worst with the fix: 0.79 px at PoE 0.5). With the plain surface Hausdorff
    distance as cluster error this failed (2.1 px at PoE 0.5, 2.8 px at PoE 1, 4.3 px at PoE 2):
    feet and limbs flattened into two-sided sheets are close to the surface but cover no pixel
    seen edge-on; the normal-compatible distance (lod.simplify.distance.cluster_hausdorff) bounds it."""
    worst, where, refined = 0.0, None, 0
    walker.sel.poe = poe
    for st, cam, ref, case in walker.cases:
        dl = walker.sel.select(st, cam, SIZE)
        refined += dl.stats["triangles"] < walker.c.mesh.n_triangles // 2
        walker.r.draw(dl, background=BG)
        err = silhouette_error(ref, _mask(walker.r.read_pixels())) / SS
        if err > worst:
            worst, where = err, case
    assert refined == len(walker.cases)  # every cut is really simplified
    assert worst <= poe + np.sqrt(2.0) / SS, (worst, "(clip, time, heading, depth)", where)


@pytest.mark.parametrize("strategy", rc.STRATEGIES)
def test_geomorph_ends_render_the_two_cuts_exactly(scene, strategy):
    """A geomorphed union (lod/clusters/morph.py, shaders/clusters/clusters_morph.vert) renders exactly
    cut A at t = 0 and exactly cut B at t = 1, pixel for pixel; in between it is neither."""
    import copy

    from lod.clusters import morph as cm

    st = _state(*CROWD)
    cam = Camera.look_at((0, 1.2, 5.0), (0, 0.9, 0))
    # geomorphed rows stay on the hardware path (render/raster/hook.py): the ends through it too, to compare exactly
    img_a, dl_a = _render(scene, scene.sel, st, cam, poe=8.0, strategy=strategy, compute=False)
    img_b, dl_b = _render(scene, scene.sel, st, cam, poe=0.7, strategy=strategy, compute=False)
    assert [(x.rep, x.part) for x in dl_a.batches] == [(x.rep, x.part) for x in dl_b.batches] and \
        len(dl_a.batches) == 2  # two clips
    h = scene.reps[0].hierarchy
    imgs = {}
    for t in (0.0, 0.5, 1.0):
        mbs = []
        for a, b in zip(dl_a.batches, dl_b.batches):
            mb, ok = cm.morph_batch(h, a, b, t)
            assert ok.all() and np.any(mb.morph_height >= 0)
            mbs.append(mb)
        dl = copy.copy(dl_a)
        dl.batches = mbs
        scene.r.draw(dl, background=BG)
        imgs[t] = scene.r.read_pixels()
        stats = scene.r.drawer("clusters").last_stats
        assert stats["instances"] == 3 and stats["morph_rows"] > 3
    assert not np.array_equal(img_a, img_b)
    assert np.array_equal(imgs[0.0], img_a)
    assert np.array_equal(imgs[1.0], img_b)
    mid = imgs[0.5]
    assert not np.array_equal(mid, img_a) and not np.array_equal(mid, img_b)
    # the half-way silhouette lies between the two: no pixel covered by neither cut appears
    assert not np.any(_mask(mid) & ~_mask(img_a) & ~_mask(img_b) & ~ndimage.binary_dilation(
        _mask(img_a) | _mask(img_b), iterations=2))


def test_geomorph_shader_constants_match_python():
    """morph.glsl (the geomorph shaders) follows collapse chains of at most lod.clusters.morph.MAX_CHAIN steps
    and addresses its textures MORPH_TEXTURE_WIDTH texels wide."""
    import re

    from lod.clusters import morph as cm
    from render.clusters.morph import MORPH_TEXTURE_WIDTH
    from render.shaders import load_source

    src = load_source("morph.glsl")
    assert int(re.search(r"const int MAX_CHAIN = (\d+);", src).group(1)) == cm.MAX_CHAIN
    w = MORPH_TEXTURE_WIDTH
    assert f"t & {w - 1}" in src and f"t >> {w.bit_length() - 1}" in src


def test_the_full_mesh_is_posed_only_when_the_compute_path_pays_for_it(scene):
    """The compute rasteriser draws a cut from the pose cache's full mesh posed in every distinct pose; a frame
    whose cuts all go to the hardware path (large on screen) must not pay that pass (it did: 4 M vertices a frame
    on the office scene), nor one routing too few triangles there to pay for it (a few far steers cost the
    stampede 30-50 ms); a far crowd whose cuts draw more triangles than the pass skins vertices takes it
    (render/raster/hook.py split_clusters, POSE_PAYS_TRIANGLES)."""
    from lod.clusters.cut import cut_triangle_count
    from lod.poses import PoseSharing
    from render.raster.hook import POSE_PAYS_TRIANGLES

    ps = PoseSharing()  # copies in one pose share it, as the engine attaches them
    ps.register([*scene.reps, *scene.full])
    scene.sel.poe = 0.5
    far = Camera.look_at((0, 1.0, 60.0), (0, 0.9, 0))

    def draw(state, cam):
        dl = scene.sel.select(state, cam, SIZE)
        ps.assign(dl)
        assert dl.poses is not None and dl.stats["clusters"] > 0
        scene.r.draw(dl, background=BG)
        return dl

    def crowd(n):  # n copies in one pose (one posed mesh), side by side
        return _state([[0.8 * (i % 10) - 4.0, 0, -1.0 * (i // 10)] for i in range(n)], [0.0] * n, [0.3] * n)

    dl = draw(_state([[0, 0, 0]], [0.0], [0.3]), Camera.look_at((0, 1.0, 2.5), (0, 0.9, 0)))
    assert dl.stats["raster_triangles"] == 0 and scene.r.poses.last_stats["posed_vertices"] == 0
    dl = draw(crowd(1), far)  # one small copy: its cut is far cheaper drawn than the mesh posed
    assert dl.stats["raster_triangles"] == 0 and scene.r.poses.last_stats["posed_vertices"] == 0
    n = 60
    dl = scene.sel.select(crowd(n), far, SIZE)
    b = next(b for b in dl.batches if getattr(b, "clusters", None) is not None)
    per = int(cut_triangle_count(scene.reps[0].hierarchy, b.offsets, b.clusters).sum())
    assert per >= POSE_PAYS_TRIANGLES * scene.c.mesh.n_vertices  # the crowd pays for its pose pass
    dl = draw(crowd(n), far)
    assert dl.stats["raster_triangles"] > 0
    assert scene.r.poses.last_stats["posed_vertices"] == scene.c.mesh.n_vertices  # one pose
    assert dl.stats["posed_vertices"] == scene.c.mesh.n_vertices  # the drawn list counts the pass (frames.csv)
