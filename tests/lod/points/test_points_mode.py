"""LOD mode "points" (lod/points/mode.py): build with the on-disk cache, skinned
baking, per-instance traversal kernel against its reference, selection stats."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "fixtures"))

from lod.points import jobs as pm_jobs  # noqa: E402
from lod.points import mode as pm  # noqa: E402
from lod.points import rep as pm_rep  # noqa: E402
from lod.modes import MODES, mode_params  # noqa: E402
from lod.view import Camera  # noqa: E402
from sim.state import CrowdState  # noqa: E402


@pytest.fixture(scope="module")
def skinned():
    from tiny_characters import tiny_skinned

    return tiny_skinned()


@pytest.fixture
def cache(tmp_path):
    return pm.HierarchyCache(tmp_path / "cache")


def test_mode_is_registered_with_its_params():
    assert MODES["points"] == "lod.points.mode"
    p = mode_params("points")
    assert p["splat_size"].default == 2 and p["splat_size"].min == 1 and p["splat_size"].max == 3
    assert p["renderer"].choices == ("compute", "gl_points")


def test_skinned_character_is_baked_one_hierarchy_per_segment(skinned, cache):
    reps, sel = pm.build([skinned], ["col"], [30], {"animation": "baked", "keyframes": 4}, cache=cache, progress=lambda it, d: it)
    rep = reps[0]
    assert rep.kind == "points" and rep.key == "points:col"
    # "bend" loops (4 segments), "twist" does not (3 segments)
    assert rep.n_parts == 7 == rep.keyframed.n_parts
    assert cache.misses == 7 and cache.hits == 0
    for s, h in enumerate(rep.hierarchies):
        assert np.isfinite(h.pos0).all() and np.isfinite(h.pos1).all() and np.isfinite(h.col0).all()
        tris = rep.segment_triangles(s)
        assert tris.shape == (h.tri_order.shape[0], 3)
        assert tris.max() < rep.keyframed.positions0.shape[0]


def test_second_build_hits_the_cache_with_identical_arrays(skinned, cache):
    a, _ = pm.build([skinned], ["col"], [30], {"animation": "baked", "keyframes": 3}, cache=cache, progress=lambda it, d: it)
    c2 = pm.HierarchyCache(cache.folder)
    b, _ = pm.build([skinned], ["col"], [30], {"animation": "baked", "keyframes": 3}, cache=c2, progress=lambda it, d: it)
    assert c2.misses == 0 and c2.hits == a[0].n_parts
    for ha, hb in zip(a[0].hierarchies, b[0].hierarchies):
        for k, v in ha.__dict__.items():
            if isinstance(v, np.ndarray):
                np.testing.assert_array_equal(v, getattr(hb, k), err_msg=k)
    # another parameter set is another key
    c3 = pm.HierarchyCache(cache.folder)
    pm.build([skinned], ["col"], [30], {"animation": "baked", "keyframes": 3, "intervals": 2}, cache=c3, progress=lambda it, d: it)
    assert c3.hits == 0 and c3.misses == a[0].n_parts


@pytest.mark.parametrize("damage", ["truncate", "flip", "digest"])
def test_a_corrupted_entry_is_detected_and_rebuilt(skinned, cache, damage):
    a, _ = pm.build([skinned], ["col"], [30], {"animation": "baked", "keyframes": 2}, cache=cache, progress=lambda it, d: it)
    npz = sorted(cache.folder.glob("*.npz"))[0]
    raw = npz.read_bytes()
    if damage == "truncate":
        npz.write_bytes(raw[: len(raw) // 2])
    elif damage == "flip":
        npz.write_bytes(raw[:200] + bytes([raw[200] ^ 0xFF]) + raw[201:])
    else:
        npz.with_suffix(".sha256").write_text("0" * 64 + "\n")
    c2 = pm.HierarchyCache(cache.folder)
    b, _ = pm.build([skinned], ["col"], [30], {"animation": "baked", "keyframes": 2}, cache=c2, progress=lambda it, d: it)
    assert c2.misses == 1 and c2.hits == a[0].n_parts - 1
    assert npz.read_bytes() == raw  # rewritten, same deterministic content
    for ha, hb in zip(a[0].hierarchies, b[0].hierarchies):
        np.testing.assert_array_equal(ha.pos0, hb.pos0)


def test_cache_dir_comes_from_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv(pm_rep.CACHE_ENV, str(tmp_path / "x"))
    assert pm_rep.cache_dir() == tmp_path / "x"
    monkeypatch.delenv(pm_rep.CACHE_ENV)
    assert pm_rep.cache_dir() == Path.home() / ".cache" / "crowd"


def _instances(rng, k, rep, spread=6.0):
    data = np.zeros((k, 16))
    for r in range(k):
        a = rng.uniform(0, 2 * np.pi)
        s = rng.uniform(0.5, 2.0)
        c, si = np.cos(a) * s, np.sin(a) * s
        data[r, :12] = [c, 0, si, rng.uniform(-spread, spread), 0, s, 0, rng.uniform(-2, 2),
                        -si, 0, c, rng.uniform(-spread, spread) - 8.0]
        data[r, 12] = rng.uniform(0, 1)
    return data


def test_instance_kernel_matches_the_per_instance_reference(skinned, cache):
    reps, _ = pm.build([skinned], ["col"], [30], {"animation": "baked", "keyframes": 3}, cache=cache, progress=lambda it, d: it)
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y=60)
    planes = cam.frustum_planes(4 / 3)
    rng = np.random.default_rng(3)
    data = _instances(rng, 40, reps[0])
    data[3, 12] = np.nan  # non-finite u is treated as 0
    data[5, 3:12:4] = [0.0, -1.0, 0.0]  # camera inside the box: must descend, not divide by 0
    for h in reps[0].hierarchies[:3]:
        for splat in (1, 2, 3):
            pj, tj = pm_jobs.traverse_instances(h, data, planes, 400.0, splat)
            ref = data.copy()
            ref[3, 12] = 0.0
            rp, rt = pm_jobs.traverse_instances_reference(h, ref, planes, 400.0, splat)
            np.testing.assert_array_equal(pj, rp)
            np.testing.assert_array_equal(tj, rt)
    # the camera-inside instance draws every triangle of the nearby nodes and no NaN arises
    assert (tj[:, 0] == 5).any()


def test_selector_stats_and_camera_inside_bounds(skinned, cache):
    reps, sel = pm.build([skinned], ["col"], [30], {"animation": "baked", "keyframes": 3, "splat_size": 1}, cache=cache,
                         progress=lambda it, d: it)
    st = CrowdState.empty(3)
    st.position[:] = [[0, 0, 0], [0, 0, -60], [0, 0, 500]]
    st.clip[:] = [0, 1, 0]
    st.anim_time[:] = [0.2, 0.5, 0.1]
    far = sel.select(st, Camera.look_at((0, 1.5, 80), (0, 1.5, 0), fov_y=40), (64, 48))
    assert far.stats["instances"] == 2 and far.stats["culled"] == 1
    assert far.stats["points"] > 0 and far.stats["points"] == sum(b.points for b in far.batches)
    assert far.stats["triangles"] == sum(b.triangles for b in far.batches)
    near = sel.select(st, Camera.look_at((0, 1.5, 0.05), (0, 1.5, -1), fov_y=40), (64, 48))  # inside a box
    assert near.stats["triangles"] > 0
    for b in near.batches:
        assert np.isfinite(b.instance_data).all()
        assert (b.point_jobs[:, 2] > 0).all() and (b.tri_jobs[:, 2] > 0).all()


def test_only_the_played_clips_get_point_hierarchies(skinned, cache):
    full, _ = pm.build([skinned], ["col"], [30], {"animation": "baked", "keyframes": 4}, cache=cache, progress=False)
    c2 = pm.HierarchyCache(cache.folder)
    reps, sel = pm.build([skinned], ["col"], [30], {"animation": "baked", "keyframes": 4}, cache=c2, progress=False, clips=[["bend"]])
    rep, ref = reps[0], full[0]
    kf = rep.keyframed
    played = pm.played_segments(kf, ["bend"])
    assert played.tolist() == [True] * 4 + [False] * 3  # "bend": 4 segments, "twist": 3
    assert c2.hits == 4 and c2.misses == 0  # the played segments are the same cached hierarchies
    for s in range(rep.n_parts):
        h = rep.hierarchies[s]
        if played[s]:
            np.testing.assert_array_equal(h.pos0, ref.hierarchies[s].pos0)
        else:  # one node with every triangle, no points
            assert h.n_nodes == 1 and h.n_points == 0 and h.child_count[0] == 0
            assert np.array_equal(np.sort(h.tri_order), np.arange(h.indices.shape[0]))
    assert rep.nbytes < ref.nbytes
    # an agent on the unbuilt clip is still drawn, as triangles, at any distance
    st = CrowdState.empty(1)
    st.clip[:] = 1
    st.anim_time[:] = 0.3
    dl = sel.select(st, Camera.look_at((0, 1.5, 400), (0, 1.5, 0), fov_y=40), (64, 48))
    assert dl.stats["points"] == 0 and dl.stats["triangles"] == rep.hierarchies[4].indices.shape[0]
    assert pm.played_segments(kf, [1]).tolist() == [False] * 4 + [True] * 3
    with pytest.raises(ValueError, match="unknown clip 'jump'"):
        pm.played_segments(kf, ["jump"])
    with pytest.raises(ValueError, match="clip index 5"):
        pm.played_segments(kf, [5])
    with pytest.raises(ValueError, match="one entry per character"):
        pm.build([skinned], ["col"], [30], {"animation": "baked", "keyframes": 4}, cache=c2, progress=False, clips=[None, None])
