"""LOD mode "triangles" (lod/chains/mode.py): the discrete chain, its cache,
per-instance level selection, equality with NoLOD at a zero bound, measured
silhouette error within the bound, and a `crowd run` with the mode."""
import csv
from types import SimpleNamespace

import numpy as np
import pytest

from lod import modes
from lod.full import mode as nolod
from lod.full import reps as nolod_reps
from lod.simplify import distance as qem_distance
from lod.chains import chain as tm_chain
from lod.chains import mode as tm
from lod.view import Camera
from sim.procedural import humanoid

from crowd_testutil import run_cli, tiny_scene
from image_checks import silhouette_error
from tiny_characters import tiny_keyframed

SIZE = (320, 240)
BG = (0.1, 0.1, 0.12)


@pytest.fixture(scope="module")
def char():
    return humanoid(2500, 0)


@pytest.fixture(scope="module")
def built(char):
    reps, sel = tm.build([char], ["h"], [30], {"poe": 0.0}, cache=False)
    full, fsel = nolod.build([char], ["h"], [30], {})
    return SimpleNamespace(rep=reps[0], sel=sel, full=full, fsel=fsel)


def _state(pos, heading=None, t=None, clip=None, character=None):
    pos = np.asarray(pos, float).reshape(-1, 3)
    n = len(pos)
    return SimpleNamespace(n=n, character=np.zeros(n, np.int64) if character is None else np.asarray(character),
                           clip=np.zeros(n, np.int64) if clip is None else np.asarray(clip, np.int64),
                           anim_time=np.zeros(n) if t is None else np.asarray(t, float), position=pos,
                           scale=np.ones(n), heading=np.zeros(n) if heading is None else np.asarray(heading, float))


# ------------------------------------------------------------------------------------------ chain
def test_registered_with_params():
    assert modes.MODES["triangles"] == "lod.chains.mode"
    p = modes.mode_params("triangles")
    assert (p["poe"].default, p["levels"].default, p["ratio"].default) == (1.0, 7, 0.5)


def test_chain_invariants(built, char):
    r = built.rep
    assert isinstance(r, nolod_reps.SkinnedRep) and r.kind == "skinned" and r.key == "triangles:h"
    assert 6 <= r.n_levels <= 7
    cnt = r.level_count
    assert cnt[0] == char.mesh.n_triangles == r.n_triangles
    np.testing.assert_array_equal(r.part_triangles(), [cnt[0]] * r.n_parts)
    ratios = cnt[1:] / cnt[:-1]
    assert np.all(ratios < 0.6) and np.all(ratios[:-1] > 0.4), ratios
    np.testing.assert_array_equal(r.level_first, np.concatenate([[0], np.cumsum(cnt)[:-1]]))
    assert r.indices.shape == (cnt.sum(), 3) and r.indices.dtype == np.uint32
    e = r.level_error
    assert e[0] == 0.0 and np.all(e[1:] > 0) and np.all(np.diff(e) >= 0) and np.isfinite(e).all()
    V = r.positions.shape[0]
    for k in range(r.n_levels):
        t = r.level_indices(k)
        assert t.shape[0] == cnt[k] and t.max() < V
        assert np.all((t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2]))
    np.testing.assert_array_equal(r.level_indices(0), np.asarray(char.mesh.indices).reshape(-1, 3))
    # vertex data shared with the full-detail rep: every level skins like the full mesh
    full = built.full[0]
    for name in ("positions", "joints", "weights", "joint_table", "clip_sphere"):
        np.testing.assert_array_equal(getattr(r, name), getattr(full, name))


def test_level_error_bounds_measured_distance(built, char):
    """The stored error is at least the vertex-to-surface distance at the sampled poses."""
    from lod.clusters import poses
    from lod.clusters.dag import skin_poses
    mats, _, _ = poses.representative_poses(char)
    X = skin_poses(char.mesh, mats[::5])
    r = built.rep
    for k in (1, 3):
        d = qem_distance.vertex_surface_distance(X, r.level_indices(0), r.level_indices(k))
        assert d.max() <= r.level_error[k] + 1e-9
        assert d.max() > 0.0


def test_short_chain_and_bad_params(char):
    sk = nolod_reps.build_skinned_rep(char, key="x")
    chain, err, _ = tm_chain.build_chain(char, sk, levels=1)
    assert len(chain) == 1 and err.tolist() == [0.0]
    with pytest.raises(ValueError, match="ratio"):
        tm_chain.build_chain(char, sk, levels=3, ratio=1.5)
    with pytest.raises(ValueError, match="poe"):
        tm.TrianglesSelector([], poe=float("nan"))


def test_cache_round_trip_and_corrupt_file(char, tmp_path):
    sk = nolod_reps.build_skinned_rep(char, key="x")
    c1, e1, k1 = tm_chain.cached_chain(char, sk, 4, 0.5, directory=tmp_path)
    files = list(tmp_path.glob("triangles-*.npz"))
    assert len(files) == 1 and not list(tmp_path.glob("*.tmp"))
    c2, e2, k2 = tm_chain.cached_chain(char, sk, 4, 0.5, directory=tmp_path)
    assert len(c1) == len(c2) == 4
    for a, b in zip(c1, c2):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(e1, e2)
    np.testing.assert_array_equal(k1[0], k2[0])
    np.testing.assert_array_equal(k1[1], k2[1])
    files[0].write_bytes(b"garbage")
    c3, e3, _ = tm_chain.cached_chain(char, sk, 4, 0.5, directory=tmp_path)
    np.testing.assert_array_equal(e3, e1)
    tm_chain._load(files[0], sk.positions.shape[0])  # rewritten: loads again
    tm_chain.cached_chain(char, sk, 3, 0.5, directory=tmp_path)
    assert len(list(tmp_path.glob("triangles-*.npz"))) == 2  # other parameters, other key


# ------------------------------------------------------------------------------------------ selection
def test_choose_levels_rule():
    err = np.array([0.0, 0.01, 0.02, 0.08])
    sphere = np.array([0.0, 1.0, 0.0, 1.0])
    z = np.array([0.5, 5.0, 20.0, 80.0, 1e6])
    rows = np.zeros((z.size, 3, 4))
    rows[:, :, :3] = np.eye(3)
    rows[:, 2, 3] = -z
    lv = tm.choose_levels(err, rows, sphere, 300.0, 1.0)
    d = np.linalg.norm(np.stack([np.zeros_like(z), np.ones_like(z), -z], 1), axis=1) - 1.0
    ref = [0 if dd <= 0 else max(k for k in range(4) if err[k] * 300 / dd <= 1.0) for dd in d]
    assert lv.tolist() == ref
    assert lv[0] == 0 and lv[-1] == 3 and np.all(np.diff(lv) >= 0)
    assert tm.choose_levels(err, rows, sphere, 300.0, 0.0).tolist() == [0] * z.size
    rows2 = rows.copy()
    rows2[:, :, :3] *= 2.0  # twice as big: twice the projected error and radius
    assert np.all(tm.choose_levels(err, rows2, sphere, 300.0, 1.0) <= lv)


def _crowd(n=60, seed=3, half_width=20.0, depth=60.0):
    rng = np.random.default_rng(seed)
    pos = np.column_stack([rng.uniform(-half_width, half_width, n), np.zeros(n), rng.uniform(-depth, 5, n)])
    return _state(pos, rng.uniform(0, 6.3, n), rng.uniform(0, 2, n))


def test_every_visible_instance_drawn_once(built):
    st = _crowd()
    cam = Camera.look_at((0, 1.6, 8.0), (0, 1.0, -10.0))
    sel = built.sel
    ref = built.fsel.select(st, cam, SIZE)
    ref_ids = np.sort(np.concatenate([b.instance_ids for b in ref.batches]))
    for poe in (0.0, 1.0, 5.0, 1e3):
        sel.poe = poe
        dl = sel.select(st, cam, SIZE)
        ids = np.concatenate([b.instance_ids for b in dl.batches])
        assert np.array_equal(np.sort(ids), ref_ids)  # none twice, none dropped
        assert sum(dl.stats["levels"]) == ids.size == dl.stats["instances"]
        assert dl.stats["triangles"] == sum(b.triangles for b in dl.batches)
        keys = [(b.rep, b.part, b.level) for b in dl.batches]
        assert len(set(keys)) == len(keys) and keys == sorted(keys)
        for b in dl.batches:
            f, c = b.index_range
            assert f == 3 * built.rep.level_first[b.level] and c == 3 * built.rep.level_count[b.level]
            assert b.triangles == built.rep.level_count[b.level] * b.n_instances
        if poe == 0.0:
            assert dl.stats["triangles"] == ref.stats["triangles"]
            assert dl.stats["levels"][0] == ids.size
    assert dl.stats["levels"][-1] > 0  # a huge bound reaches the coarsest level
    sel.poe = 0.0


def test_keyframed_character_falls_back_to_full_detail(char):
    kf = tiny_keyframed()
    reps, sel = tm.build([char, kf], ["h", "flag"], [30, 30], {"poe": 2.0}, cache=False)
    assert isinstance(reps[0], tm_chain.TrianglesRep) and reps[1].kind == "keyframed"
    st = _state([[0, 0, 0], [1, 0, 0], [30, 0, -40]], character=[0, 1, 0])
    dl = sel.select(st, Camera.look_at((0, 1.5, 6), (0, 1, 0)), SIZE)
    kb = [b for b in dl.batches if b.rep == "triangles:flag"]
    assert kb and all(getattr(b, "index_range", None) is None and b.level == 0 for b in kb)
    assert sum(dl.stats["levels"]) == dl.stats["instances"] >= 2


# ------------------------------------------------------------------------------------------ rendering
@pytest.fixture(scope="module")
def gl(built):
    from render.context import create_context
    from render.renderer import Renderer
    ctx = create_context()
    rs = {}
    for ss in (1, 4):
        r = Renderer((SIZE[0] * ss, SIZE[1] * ss), ctx=ctx)
        for rep in [built.rep, *built.full]:
            r.upload(rep)
        rs[ss] = r
    yield rs
    for r in rs.values():
        r.release()
    ctx.release()


def _mask(img):
    bg = np.round(np.asarray(BG) * 255).astype(int)
    return np.abs(img.astype(int) - bg).max(axis=2) > 2


def _draw(r, dl):
    r.draw(dl, background=BG)
    return r.read_pixels()


def test_poe_zero_is_pixel_identical_to_nolod(built, gl):
    st = _crowd(30, 5, half_width=5.0, depth=25.0)
    cam = Camera.look_at((0, 1.6, 8.0), (0, 1.0, -10.0))
    built.sel.poe = 0.0
    ref_dl = built.fsel.select(st, cam, SIZE)
    dl = built.sel.select(st, cam, SIZE)
    ref, img = _draw(gl[1], ref_dl), _draw(gl[1], dl)
    assert _mask(ref).sum() > 1000
    assert dl.stats["triangles"] == ref_dl.stats["triangles"] and dl.n_instances == ref_dl.n_instances
    assert np.array_equal(img, ref)
    # plain DrawBatches of the chain rep (no index_range, e.g. re-based by a frozen view) draw level 0 only
    from dataclasses import replace
    from lod.drawlist import DrawBatch
    plain = replace(dl, batches=[DrawBatch(b.rep, b.part, b.instance_ids, b.instance_data) for b in dl.batches])
    assert np.array_equal(_draw(gl[1], plain), ref)
    # the comparison can fail: coarse levels change the image and draw fewer triangles
    built.sel.poe = 50.0
    dl = built.sel.select(st, cam, SIZE)
    assert dl.stats["triangles"] < ref_dl.stats["triangles"]
    assert not np.array_equal(_draw(gl[1], dl), ref)
    built.sel.poe = 0.0


@pytest.mark.parametrize("poe", [1.0, 3.0])
def test_silhouette_error_within_poe(built, gl, poe):
    """One instance at distances where the bound picks levels > 0: rendered at
    4x the selection resolution, the silhouette of the chosen level stays within
    ``poe`` (+1 pixel of rasterisation) of level 0's."""
    r = gl[4]
    sel = built.sel
    seen = set()
    for z, t, heading in ((-4.0, 0.3, 0.4), (-10.0, 0.9, 1.2), (-25.0, 0.1, 2.0), (-60.0, 0.6, 0.0)):
        st = _state([[0.0, 0.0, z]], [heading], [t])
        cam = Camera.look_at((0, 1.0, 3.0), (0, 0.9, z))
        sel.poe = 0.0
        full = _mask(_draw(r, sel.select(st, cam, SIZE)))
        sel.poe = poe
        dl = sel.select(st, cam, SIZE)
        (b,) = dl.batches
        seen.add(b.level)
        err = silhouette_error(full, _mask(_draw(r, dl))) / 4.0
        assert err <= poe + 1.0, (z, b.level, err)
    assert max(seen) >= 2
    sel.poe = 0.0


def test_index_range_is_checked(built, gl):
    from lod.drawlist import DrawList
    st = _state([[0, 0, -5.0]])
    cam = Camera.look_at((0, 1.0, 3.0), (0, 0.9, -5.0))
    dl = built.sel.select(st, cam, SIZE)
    dl.batches[0].index_range = (0, 3 * int(built.rep.level_count.sum()) + 3)
    with pytest.raises(ValueError, match="index_range"):
        gl[1].draw(dl)
    assert isinstance(dl, DrawList)


# ------------------------------------------------------------------------------------------ crowd run
def test_crowd_run_with_mode_triangles(tmp_path):
    scene = tmp_path / "tiny.toml"
    scene.write_text(tiny_scene(replace={'mode = "none"': 'mode = "triangles"\npoe = 1.0\nlevels = 5',
                                         "position = [1.0, 2.0, 7.0]": "position = [1.0, 2.0, 30.0]"}))
    p = run_cli("run", scene, "--out", tmp_path / "out", "--quiet")
    assert p.returncode == 0, p.stderr
    rows = list(csv.DictReader(open(tmp_path / "out" / "frames.csv")))
    assert len(rows) == 3
    tri = [int(float(r["triangles"])) for r in rows]
    assert all(0 < t < 4 * 600 for t in tri), tri  # far away: coarser than full detail


# ------------------------------------------------------------------------------------------ geomorph collapses
def test_vertex_collapses_map_each_level_onto_every_coarser_one(built):
    """Following the collapses of a level's vertices up to a coarser level turns its triangles into
    exactly that level's triangles (plus degenerate ones): what TriangleDrawBatch.morph draws at
    weight 1 (lod.clusters.morph.chain_targets: the walk the shaders run)."""
    from lod.clusters.morph import chain_targets

    r = built.rep
    nxt, lvl = r.collapse_next, r.collapse_level
    assert nxt.shape == lvl.shape == (r.positions.shape[0],)
    for fine in range(r.n_levels - 1):
        for coarse in range(fine + 1, r.n_levels):
            t = chain_targets(nxt, lvl, r.level_indices(fine).reshape(-1), coarse).reshape(-1, 3)
            keep = (t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2])

            def canon(a):
                a = np.asarray(a, np.int64)
                k = np.argmin(a, axis=1)
                return sorted(map(tuple, np.stack([a[np.arange(len(a)), (k + j) % 3] for j in range(3)], 1)))
            assert canon(t[keep]) == canon(r.level_indices(coarse))
    # a vertex of level L keeps itself up to L (its walk starts above it)
    v = np.unique(r.level_indices(2))
    assert np.array_equal(chain_targets(nxt, lvl, v, 2), v)


def test_corrupt_collapses_in_the_cache_are_rebuilt(char, tmp_path):
    sk = nolod_reps.build_skinned_rep(char, key="x")
    c1, e1, k1 = tm_chain.cached_chain(char, sk, 3, 0.5, directory=tmp_path)
    f = next(tmp_path.glob("triangles-*.npz"))
    with np.load(f) as z:
        d = dict(z)
    moved = np.flatnonzero(d["collapse_next"] != np.arange(d["collapse_next"].shape[0]))
    d["collapse_level"][d["collapse_next"][moved[0]]] = 0  # a chain that descends
    np.savez(f, **d)
    with pytest.raises(ValueError, match="collapses"):
        tm_chain._load(f, sk.positions.shape[0])
    c2, e2, k2 = tm_chain.cached_chain(char, sk, 3, 0.5, directory=tmp_path)  # rebuilt
    np.testing.assert_array_equal(k2[1], k1[1])


def test_keyframed_levels_are_geomorphed(built):
    """Keyframed selection around the triangles selector blends two different levels of an
    instance by a geomorph of the finer one (TriangleDrawBatch.morph), never fades, and with
    geomorph off fades them."""
    from lod.temporal.selection import KeyframedSelector
    from sim.state import CrowdState

    rng = np.random.default_rng(3)
    st = CrowdState.empty(30)
    st.position[:] = np.c_[rng.uniform(-5, 5, 30), np.zeros(30), rng.uniform(-80, -2, 30)]
    st.heading[:] = rng.uniform(0, 6.28, 30)
    st.scale[:] = 1.0
    for geomorph in (True, False):
        sel = KeyframedSelector(tm.TrianglesSelector([built.rep], poe=1.0), n=4, mode="current", geomorph=geomorph)
        morphs = fades = 0
        for f in range(12):
            cam = Camera.look_at((0.0, 1.6, 10.0 - 4.0 * f), (0.0, 1.0, -90.0))
            dl = sel.select(st, cam, (320, 240))
            for b in dl.batches:
                m = getattr(b, "morph", None)
                if m is not None:
                    assert b.fade is None and m[0] > b.level and 0.0 <= m[1] <= 1.0
                    assert b.index_range == (3 * int(built.rep.level_first[b.level]),
                                             3 * int(built.rep.level_count[b.level]))
                    morphs += b.n_instances
                fades += b.fade is not None
            ids = np.concatenate([b.instance_ids for b in dl.batches if b.fade is None])
            assert np.unique(ids).size == ids.size
            assert dl.stats["geomorphs"] == sum(b.n_instances for b in dl.batches
                                                if getattr(b, "morph", None) is not None)
        assert (morphs > 0, fades > 0) == ((True, False) if geomorph else (False, True))
