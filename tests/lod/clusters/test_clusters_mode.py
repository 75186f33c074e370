"""LOD mode "clusters" (lod/clusters/mode.py): registry, cache, selector, fallback, end-to-end run."""
import csv
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "fixtures"))
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "crowd"))
from tiny_characters import tiny_keyframed, tiny_skinned  # noqa: E402

from lod.clusters import mode as clusters_mode  # noqa: E402
from lod.clusters import cut as cluster_cut
from lod.clusters import dag as cluster_dag
from lod.modes import mode_names, mode_params  # noqa: E402
from lod.view import Camera  # noqa: E402
from sim.procedural import humanoid  # noqa: E402


@pytest.fixture(scope="module")
def human():
    return humanoid(1200, 1)


def _state(n, char=None, clip=None, spread=6.0, seed=0):
    rng = np.random.default_rng(seed)
    pos = np.zeros((n, 3))
    pos[:, 0] = rng.uniform(-spread, spread, n)
    pos[:, 2] = rng.uniform(-4 * spread, 0, n)
    return SimpleNamespace(n=n, character=np.zeros(n, np.int64) if char is None else np.asarray(char, np.int64),
                           clip=np.zeros(n, np.int64) if clip is None else np.asarray(clip, np.int64),
                           anim_time=rng.uniform(0, 2, n), position=pos, scale=np.ones(n),
                           heading=rng.uniform(-np.pi, np.pi, n))


def test_registered_with_its_params():
    assert "clusters" in mode_names()
    p = mode_params("clusters")
    assert set(p) >= {"poe", "occlusion", "occlusion_every"}
    assert p["poe"].default == 0.5 and p["occlusion_every"].default == 8 and p["occlusion"].default is False


def test_cache_hit_miss_and_corrupt_entry(human, tmp_path, monkeypatch):
    monkeypatch.setenv(clusters_mode.CACHE_ENV, str(tmp_path))
    calls = []
    real = clusters_mode.build_cluster_hierarchy

    def counting(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(clusters_mode, "build_cluster_hierarchy", counting)
    reps, _ = clusters_mode.build([human], ["h"], [30], {})
    files = list(tmp_path.glob("clusters-*.npz"))
    assert len(calls) == 1 and len(files) == 1
    assert not list(tmp_path.glob("*.tmp"))  # atomic write left no temp file
    reps2, _ = clusters_mode.build([human], ["h"], [30], {})
    assert len(calls) == 1  # loaded
    h1, h2 = reps[0].hierarchy, reps2[0].hierarchy
    assert np.array_equal(h1.indices, h2.indices) and np.array_equal(h1.error, h2.error)
    # a damaged file is detected and rebuilt
    files[0].write_bytes(files[0].read_bytes()[:100])
    reps3, _ = clusters_mode.build([human], ["h"], [30], {})
    assert len(calls) == 2
    assert np.array_equal(reps3[0].hierarchy.indices, h1.indices)
    assert clusters_mode.ClusterHierarchy.load(files[0]).n_clusters == h1.n_clusters
    # other build parameters, another key
    clusters_mode.build([human], ["h"], [30], {"clustering": "octree"})
    assert len(calls) == 3 and len(list(tmp_path.glob("clusters-*.npz"))) == 2
    # poe is a runtime parameter: same key
    clusters_mode.build([human], ["h"], [30], {"poe": 3.0})
    assert len(calls) == 3


def test_cache_key_depends_on_inputs(human):
    from lod.full.reps import build_skinned_rep

    a = build_skinned_rep(human, key="k")
    b = build_skinned_rep(humanoid(1200, 2), key="k")
    p = clusters_mode.build_params_of({})
    assert clusters_mode.cache_key(a, p) == clusters_mode.cache_key(a, dict(p))
    assert clusters_mode.cache_key(a, p) != clusters_mode.cache_key(b, p)
    assert clusters_mode.cache_key(a, p) != clusters_mode.cache_key(a, {"clustering_method": "octree"})
    # the leaf size: the default keeps the key of the default build, another size is another hierarchy
    assert clusters_mode.build_params_of({"leaf_triangles": 100}) == p
    big = clusters_mode.build_params_of({"leaf_triangles": 1000})
    assert big["s"] == 1000 and clusters_mode.cache_key(a, big) != clusters_mode.cache_key(a, p)


def test_unwritable_cache_still_builds(human, tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    monkeypatch.setenv(clusters_mode.CACHE_ENV, str(blocker / "sub"))  # cannot mkdir under a file
    reps, _ = clusters_mode.build([human], ["h"], [30], {})
    assert reps[0].hierarchy.n_clusters > 1


def test_selector_cuts_every_instance_and_counts_triangles(human):
    reps, sel = clusters_mode.build([human], ["h"], [30], {"poe": 1.0}, cache=False)
    h = reps[0].hierarchy
    st = _state(60, clip=np.arange(60) % 2)
    cam = Camera.look_at((0, 1.6, 6.0), (0, 1.0, -10.0))
    size = (640, 360)
    dl = sel.select(st, cam, size)
    assert dl.batches and all(isinstance(b, clusters_mode.ClusterDrawBatch) for b in dl.batches)
    assert {b.part for b in dl.batches} == {0, 1}  # one batch per (character, clip)
    scale = cluster_cut.viewport_scale(size[1], cam.fov_y)
    planes = cam.frustum_planes(size[0] / size[1])
    total = 0
    culled = 0
    for b in dl.batches:
        M = b.instance_data[:, :12].astype(np.float64).reshape(-1, 3, 4)
        ref = cluster_cut.cut_numpy(h, M, np.zeros(3), scale, 1.0)
        ro = np.concatenate([[0], np.cumsum([len(r) for r in ref])])
        co, cc = clusters_mode.cull_clusters_numpy(h.sphere, M, ro, np.concatenate(ref), planes)
        culled += len(np.concatenate(ref)) - cc.size
        assert np.array_equal(b.offsets, co) and np.array_equal(b.clusters, cc)
        assert b.triangles == int(cluster_cut.cut_triangle_count(h, b.offsets, b.clusters).sum())
        total += b.triangles
    assert dl.stats["triangles"] == total
    assert dl.stats["clusters"] == sum(b.clusters.size for b in dl.batches)
    n_vis = dl.stats["instances"]
    assert 0 < total < n_vis * h.n_triangles  # far instances are simplified
    # PoE 0 without culling: the original mesh for every instance
    sel.poe = 0.0
    sel.cull = False
    dl0 = sel.select(st, cam, size)
    assert dl0.stats["triangles"] == n_vis * h.n_triangles
    sel.cull = True
    # coarser PoE, fewer triangles
    sel.poe = 4.0
    assert sel.select(st, cam, size).stats["triangles"] < total


def test_keyframed_characters_fall_back_to_full_detail(human):
    kf = tiny_keyframed()
    reps, sel = clusters_mode.build([human, kf], ["h", "kf"], [30, 30], {}, cache=False)
    assert reps[0].kind == "clusters" and reps[1].kind == "keyframed"
    assert reps[1].key == "clusters:kf"
    st = _state(10, char=np.arange(10) % 2)
    dl = sel.select(st, Camera.look_at((0, 2, 8), (0, 0.5, -10)), (320, 240))
    kinds = {b.rep: type(b).__name__ for b in dl.batches}
    assert kinds.get("clusters:kf") == "DrawBatch" and kinds.get("clusters:h") == "ClusterDrawBatch"


def test_bad_parameters():
    with pytest.raises(ValueError, match="poe"):
        clusters_mode.ClustersSelector([], poe=float("nan"))
    with pytest.raises(ValueError, match="poe"):
        clusters_mode.ClustersSelector([], poe=-1.0)


def test_empty_crowd_and_tiny_character():
    reps, sel = clusters_mode.build([tiny_skinned()], ["t"], [30], {}, cache=False)
    st = _state(0)
    dl = sel.select(st, Camera.look_at((0, 1, 5), (0, 1, 0)), (64, 48))
    assert dl.batches == [] and dl.stats["triangles"] == 0 and dl.stats["clusters"] == 0


def test_crowd_run_end_to_end_reports_triangles(tmp_path, monkeypatch):
    from crowd_testutil import run_cli, tiny_scene

    monkeypatch.setenv(clusters_mode.CACHE_ENV, str(tmp_path / "cache"))
    scene = tmp_path / "s.toml"
    scene.write_text(tiny_scene(replace={'mode = "none"': 'mode = "clusters"\npoe = 1.0'}))
    out = tmp_path / "out"
    r = run_cli("run", scene, "--out", out, "--quiet")
    assert r.returncode == 0, r.stderr
    rows = list(csv.DictReader((out / "frames.csv").open()))
    assert len(rows) == 3
    assert all(int(float(row["triangles"])) > 0 for row in rows)
    assert len(list((out / "frames").iterdir())) == 3
    assert list((tmp_path / "cache").glob("clusters-*.npz"))  # the hierarchy was cached


def test_cluster_culling_kernel_matches_reference_and_keeps_visible_clusters(human):
    reps, _ = clusters_mode.build([human], ["h"], [30], {}, cache=False)
    h = reps[0].hierarchy
    rng = np.random.default_rng(7)
    k = 30
    rows = np.zeros((k, 3, 4))
    for i in range(k):
        a = rng.uniform(-np.pi, np.pi)
        s = rng.uniform(0.5, 2.0)
        rows[i, :, :3] = s * np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
        rows[i, :, 3] = rng.uniform(-6, 6, 3) + [0, -1, -6]
    offsets, clusters = cluster_cut.cut(h, rows, np.zeros(3), 500.0, 0.0)
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y=40.0)
    planes = cam.frustum_planes(1.5)
    a = clusters_mode.cull_clusters(reps[0].sphere64, rows, offsets, clusters, planes)
    b = clusters_mode.cull_clusters_numpy(h.sphere, rows, offsets, clusters, planes)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert 0 < a[1].size < clusters.size
    # every vertex of a dropped cluster, in every sampled pose's bounds, is outside the frustum:
    # check with the cluster's AABB corners in the rest pose (inside the sphere)
    kept = set()
    for i in range(k):
        kept |= {(i, int(c)) for c in a[1][a[0][i]:a[0][i + 1]]}
    for i in range(k):
        for c in clusters[offsets[i]:offsets[i + 1]]:
            if (i, int(c)) in kept:
                continue
            v = np.unique(h.cluster_triangles(int(c)))
            pts = human.mesh.positions[v] @ rows[i, :, :3].T + rows[i, :, 3]
            d = pts @ planes[:, :3].T + planes[:, 3]
            assert np.any(np.all(d < 0, axis=0))  # all points behind one plane
    # empty input
    e = clusters_mode.cull_clusters(reps[0].sphere64, np.zeros((0, 3, 4)), np.zeros(1, np.int64),
                                    np.zeros(0, np.int32), planes)
    assert e[0].tolist() == [0] and e[1].size == 0
