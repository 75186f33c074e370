"""The far tier's splat (render/far/draw.py, lod/far): a far agent's pixel carries the covered area and mean lit
colour of the character drawn at full detail (issue 45: within 2/255 and 5 %), and the tier's selection
draws every agent in exactly one tier."""
from types import SimpleNamespace

import numpy as np
import pytest

from lod.far.rep import build_far_rep
from lod.far.select import FAR, FarSplit
from lod.full.mode import NoLodSelector
from lod.full.reps import build_skinned_rep
from lod.points.traverse import viewport_scale
from lod.view import Camera
from render.renderer import Renderer
from sim.procedural import humanoid
from sim.state import CrowdState

HEADING = 0.7
LIGHT = np.array([0.35, 0.85, 0.4]) / np.linalg.norm([0.35, 0.85, 0.4])  # the renderer's default light


@pytest.fixture(scope="module")
def walker(gl_ctx):
    rep = build_skinned_rep(humanoid(1500, 5))
    far = build_far_rep(rep, "w", clips=[0])
    return SimpleNamespace(rep=rep, far=far, gl=gl_ctx)


def _view(el_deg, az_deg):
    """Unit direction from the agent to the camera, world, for a view (el, az) in the agent's frame."""
    el, az = np.radians(el_deg), np.radians(az_deg) + HEADING  # world azimuth = local + heading
    return np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])


def _state(n=1, times=(0.0,)):
    st = CrowdState.empty(n)
    st.heading[:] = HEADING
    st.scale[:] = 1.0
    st.anim_time[:] = times
    return st


def _crowd(n, seed, half_width, z_range):
    """``n`` walkers at random phases, x within +-half_width, z within z_range (m)."""
    rng = np.random.default_rng(seed)
    st = _state(n, rng.uniform(0.0, 1.0, n))
    st.position[:, 0] = rng.uniform(-half_width, half_width, n)
    st.position[:, 2] = rng.uniform(*z_range, n)
    return st


def _reference(w, el, az, size=200, frames=12):
    """Covered area (m^2) and mean colour of the character at full detail seen from (el, az) in its frame,
    over ``frames`` times of the walk, near-orthographic (fov 2 degrees), black background."""
    dist, fov = 120.0, 2.0
    centre = w.far.tables[0].centre
    target = np.array([0.0, centre[1], 0.0])
    cam = Camera.look_at(target + dist * _view(el, az), target, fov_y=fov, near=1.0, far=500.0)
    sel = NoLodSelector([w.rep])
    dur = float(w.rep.clip_duration[0])
    r = Renderer((size, size), ctx=w.gl)
    r.tint_table = getattr(w, "tint", None)  # the agent's colour-variation word, if any
    area, colour = [], []
    try:
        r.upload(w.rep)
        for k in range(frames):
            r.draw(sel.select(_state(times=(dur * k / frames,)), cam, (size, size)), background=(0, 0, 0))
            img = r.read_pixels().astype(np.float64) / 255.0
            cov = img.max(axis=2) > 0
            pix = 2.0 * dist * np.tan(np.radians(fov) / 2) / size
            area.append(cov.sum() * pix * pix)
            colour.append(img[cov].sum(axis=0))
    finally:
        r.release()
    a = float(np.mean(area))
    return a, np.sum(colour, axis=0) / (np.sum(area) / (pix * pix))


def _bil(x, el, az):
    """``x`` (VE, VA, ...) of a far table at the view (el, az) in degrees, bilinearly (the splat's lookup)."""
    fe = (el + 90.0) / 180.0 * (x.shape[0] - 1)
    fa = (az % 360.0) / 360.0 * x.shape[1]
    e0, a0 = min(int(fe), x.shape[0] - 2), int(fa) % x.shape[1]
    te, ta = fe - e0, fa - int(fa)
    a1 = (a0 + 1) % x.shape[1]
    return (1 - te) * ((1 - ta) * x[e0, a0] + ta * x[e0, a1]) + te * ((1 - ta) * x[e0 + 1, a0] + ta * x[e0 + 1, a1])


def _lit_at_heading(t):
    """(VE, VA, 3) a far table lit by the renderer's default light turned into the agent's frame."""
    c, s = np.cos(HEADING), np.sin(HEADING)
    return t.lit(np.array([c * LIGHT[0] - s * LIGHT[2], LIGHT[1], s * LIGHT[0] + c * LIGHT[2]]))


def _one_far_agent(w, el=25.0, az=30.0, background=(0, 0, 0), blobs=False, words=None, color_by=None):
    """One agent 1,500 m away seen from (el, az) in its frame, drawn by the far tier alone at 160 x 120:
    (image (h, w, 3) in [0, 1], its one lit pixel's value, its pixels per m^2 of the agent)."""
    from lod.debug_colors import apply_tints

    size = (160, 120)
    cam = Camera.look_at(1500.0 * _view(el, az), (0.0, 0.9, 0.0), fov_y=8.0, near=1.0, far=5000.0)
    near, batches, culled = FarSplit([w.far], far_pixels=3.0).split(
        _state(), cam, size, viewport_scale(size[1], cam.fov_y), cam.frustum_planes(size[0] / size[1]))
    assert near.size == 0 and culled == 0 and len(batches) == 1 and batches[0].n_instances == 1
    r = Renderer(size, ctx=w.gl)
    try:
        r.lighting.mode = "blob" if blobs else "none"
        r.tint_table = words
        r.upload(w.far)
        dl = NoLodSelector([w.rep]).select(CrowdState.empty(0), cam, size)
        dl.batches = list(batches)
        if color_by is not None:
            apply_tints(dl, color_by)
        r.draw(dl, background=background)
        img = r.read_pixels().astype(np.float64) / 255.0
    finally:
        r.release()
    changed = np.argwhere(np.abs(img - np.asarray(background, float)).max(axis=2) > 0)
    assert changed.shape[0] == 1  # one splat, one pixel
    t = w.far.tables[0]
    dist = np.linalg.norm(1500.0 * _view(el, az) - (t.centre * [0, 1, 0]))
    px_m2 = (size[1] / (2.0 * np.tan(np.radians(cam.fov_y) / 2) * dist)) ** 2
    return img, img[tuple(changed[0])], px_m2


@pytest.mark.parametrize("el,az", [(10.0, 0.0), (35.0, 50.0), (60.0, 200.0)])
def test_footprint_matches_full_detail(walker, el, az):
    area, colour = _reference(walker, el, az)
    t = walker.far.tables[0]
    assert _bil(t.area, el, az) == pytest.approx(area, rel=0.05)
    lit = _bil(_lit_at_heading(t), el, az)
    assert np.abs(lit - colour).max() <= 2.0 / 255.0, (lit * 255, colour * 255)


def test_far_splat_pixel_is_coverage_times_colour(walker):
    """One far agent: its pixel is alpha x colour over black, alpha the covered area in pixels."""
    _, got, px_m2 = _one_far_agent(walker)
    t = walker.far.tables[0]
    alpha = _bil(t.area, 25.0, 30.0) * px_m2
    assert 0.05 < alpha < 1.0  # a fraction of a pixel
    want = alpha * _bil(_lit_at_heading(t), 25.0, 30.0)  # the shader's lookup against the CPU's at the same view
    assert np.abs(got - want).max() <= 2.0 / 255.0, (got * 255, want * 255)


def test_every_agent_in_exactly_one_tier(walker):
    """Agents walking away from the camera cross the far threshold: each frame every visible agent is in the
    far batches or goes on to the mode's own selection, never both, never neither."""
    n = 400
    st = _crowd(n, 3, 30.0, (-800.0, -50.0))
    cam = Camera.look_at((0.0, 2.0, 10.0), (0.0, 0.0, -100.0), fov_y=40.0, near=0.5, far=3000.0)
    size = (320, 240)
    vs = viewport_scale(size[1], cam.fov_y)
    split = FarSplit([walker.far], far_pixels=2.0)
    planes = cam.frustum_planes(size[0] / size[1])
    base = NoLodSelector([walker.rep])
    seen_far = set()
    for step in range(6):
        st.position[:, 2] -= 60.0 * step
        near, batches, culled = split.split(st, cam, size, vs, planes)
        far_ids = np.concatenate([b.instance_ids for b in batches]) if batches else np.zeros(0, np.int32)
        drawn_near = base.select(st, cam, size, agents=near).batches
        near_ids = np.concatenate([b.instance_ids for b in drawn_near]) if drawn_near else np.zeros(0, np.int32)
        everyone = base.select(st, cam, size).batches  # what a single tier would draw (culling only)
        visible = np.concatenate([b.instance_ids for b in everyone]) if everyone else np.zeros(0, np.int32)
        assert np.intersect1d(far_ids, near_ids).size == 0
        assert np.array_equal(np.sort(np.concatenate([far_ids, near_ids])), np.sort(visible))
        assert np.isfinite(batches[0].instance_data).all() if batches else True
        seen_far.update(far_ids.tolist())
    assert len(seen_far) > n // 2  # most crossed into the far tier


def test_mode_points_draws_far_agents_in_the_far_tier(gl_ctx, tmp_path):
    """``[lod] far_pixels`` in mode points: the far agents are one FarBatch (no traversal, no point jobs), the
    near ones points as before, and every agent is counted once."""
    from lod.far.select import FarBatch
    from lod.points import mode as pm
    from lod.points import rep as pm_rep
    from lod.points.rep import PointsBatch

    c = humanoid(1500, 5)
    cache = pm_rep.HierarchyCache(tmp_path)
    n = 300
    st = _crowd(n, 4, 60.0, (-900.0, -20.0))
    cam = Camera.look_at((0.0, 6.0, 0.0), (0.0, 0.0, -190.0), fov_y=40.0, near=0.5, far=2000.0)
    size = (320, 240)
    for far_px in (0.0, 2.0):
        reps, sel = pm.build([c], ["w"], [30], {"splat_size": 2, "keyframes": 4, "far_pixels": far_px},
                             cache=cache, progress=False)
        dl = sel.select(st, cam, size)
        fars = [b for b in dl.batches if isinstance(b, FarBatch)]
        pts = [b for b in dl.batches if isinstance(b, PointsBatch) or b.rep.startswith("points")]
        ids = np.concatenate([b.instance_ids for b in dl.batches])
        assert np.unique(ids).size == ids.size == dl.stats["instances"]
        if far_px == 0.0:
            assert not fars and "far" not in dl.stats
            continue
        assert len(fars) == 1 and 0 < fars[0].n_instances == dl.stats["far"] < n and pts
        assert any(r.kind == "far" for r in reps)
        r = Renderer(size, ctx=gl_ctx)
        try:
            for rep in reps:
                r.upload(rep)
            r.draw(dl, background=(0, 0, 0))
            img = r.read_pixels()
            assert r.uploaded_drawer("far").last_counts["far"] == fars[0].n_instances
        finally:
            r.release()
        assert np.isfinite(img).all() and img.max() > 0


def test_far_splat_hides_behind_nearer_surfaces(walker):
    """The resolve writes the far agents' depth and the fixed-function test keeps them behind a nearer
    character drawn at full detail: the frame equals the one without the far agent there."""
    size = (160, 120)
    eye = np.array([0.0, 1.0, 40.0])
    cam = Camera.look_at(eye, (0.0, 1.0, -1500.0), fov_y=30.0, near=0.5, far=5000.0)
    far_st = _state()
    far_st.position[0] = (0.0, 0.1, -1500.0)
    near_st = _state()
    near_st.heading[:] = 0.0
    split = FarSplit([walker.far], far_pixels=3.0)
    planes = cam.frustum_planes(size[0] / size[1])
    _, batches, _ = split.split(far_st, cam, size, viewport_scale(size[1], cam.fov_y), planes)
    assert len(batches) == 1
    sel = NoLodSelector([walker.rep])
    imgs = []
    r = Renderer(size, ctx=walker.gl)
    try:
        r.upload(walker.rep)
        r.upload(walker.far)
        for with_near in (False, True):
            for with_far in (False, True):
                dl = sel.select(near_st if with_near else CrowdState.empty(0), cam, size)
                if with_far:
                    dl.batches = list(dl.batches) + batches
                r.draw(dl, background=(0, 0, 0))
                imgs.append(r.read_pixels().copy())
    finally:
        r.release()
    assert not np.array_equal(imgs[0], imgs[1])  # alone, the far agent shows
    assert np.array_equal(imgs[2], imgs[3])  # behind the near one, it does not


def test_ground_shadow_is_the_visible_blob_opacity():
    from render.far.draw import ground_shadow
    from render.world.shadows import blob_opacity, blob_radius
    from lod.far.footprint import FarTable, RINGS

    shape = (9, 16)
    t = FarTable(np.ones(shape), np.zeros(shape + (3,)), np.zeros(shape + (3,)), np.zeros(shape + (9, 16, 3)), 1.0,
                 np.zeros(3), np.ones(shape + (RINGS,)), np.zeros(3), np.array([0.55, 1.8, 0.3]))
    rb = blob_radius(t.extent)
    rho = np.linspace(0, 1, 100001)
    disc = np.trapezoid(blob_opacity(rho) * 2 * np.pi * rho, rho) * rb * rb
    assert np.allclose(ground_shadow(t), disc, rtol=0.01)
    t.ground[:] = 0.0
    assert not ground_shadow(t).any()
    t.ground[:] = 0.5
    assert np.allclose(ground_shadow(t), 0.5 * disc, rtol=0.01)


def test_far_splat_darkens_the_ground_by_its_visible_blob(walker):
    """With blob shadows on, a far agent over a white frame: alpha x colour + (1 - alpha)(1 - shadow), the
    shadow its visible blob opacity foreshortened and in pixels (within 2/255)."""
    from render.far.draw import ground_shadow

    _, none, px_m2 = _one_far_agent(walker, background=(1, 1, 1))
    _, blob, _ = _one_far_agent(walker, background=(1, 1, 1), blobs=True)
    t = walker.far.tables[0]
    alpha = _bil(t.area, 25.0, 30.0) * px_m2
    shade = _bil(ground_shadow(t), 25.0, 30.0) * np.sin(np.radians(25.0)) * px_m2
    assert 0.01 < shade < 0.5
    assert np.all(blob < none)  # the blob darkens what the agent leaves uncovered
    assert np.allclose(blob, none - (1 - alpha) * shade, atol=2.0 / 255.0), (blob * 255, (none - (1 - alpha) * shade) * 255)


def test_far_splats_take_the_debug_colour_of_their_batch(walker):
    """Colour by representation (lod.debug_colors): the far batch's tint is mixed into its splats' colour."""
    from lod.debug_colors import REPRESENTATION_COLORS, TINT_WEIGHT

    _, plain, _ = _one_far_agent(walker, color_by="none")
    _, tinted, _ = _one_far_agent(walker, color_by="representation")
    rgb = np.asarray(REPRESENTATION_COLORS["far"])
    # over black, plain = a c and tinted = a mix(c, rgb, w) for the same coverage a: their difference is a w rgb
    rest = tinted - (1 - TINT_WEIGHT) * plain
    assert rest.min() > 0 and np.allclose(rest / rest.sum(), rgb / rgb.sum(), atol=0.05)


@pytest.mark.parametrize("kind", ["palette", "hsv"])
def test_far_splat_carries_the_agents_colour_variation(walker, kind):
    """An agent with a colour-variation word (lod.variation): its far pixel is its coverage times the mean lit
    colour of the character drawn at full detail with that word (within 2/255; a palette word makes the varied
    part one colour, where the far table is exact; the hue shift of a mostly one-coloured garment, close)."""
    from lod.variation import MODE_PALETTE, pack_hsv, pack_rgba8

    word = (pack_rgba8([[0.9, 0.2, 0.1]], mode=MODE_PALETTE) if kind == "palette" else pack_hsv([0.3], [1.0], [1.0]))
    table = np.asarray(word, np.uint32).reshape(1)
    el, az = 25.0, 30.0
    # the full-detail reference: mean lit colour and covered area, near-orthographic, the word applied
    ref = _reference(SimpleNamespace(rep=walker.rep, far=walker.far, gl=walker.gl, tint=table), el, az)
    plain = _reference(walker, el, az)
    assert np.abs(ref[1] - plain[1]).max() > 3 / 255  # the word changes the mean colour
    _, got, px_m2 = _one_far_agent(walker, el, az, words=table)
    alpha = _bil(walker.far.tables[0].area, el, az) * px_m2
    assert np.abs(got - alpha * ref[1]).max() <= 2.0 / 255.0, (got * 255, alpha * ref[1] * 255)
