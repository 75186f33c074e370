"""Samples that follow the animation (lod/points/follow.py, deform.py, follow_select.py; issue 27): kernels
against their numpy references, the bounds of every node at every 30 Hz sample of every clip, the spacing under
a stretching joint, the prefixes, the cache, and the characters real assets give (degenerate triangles,
unnormalised weights, rigid parts, no clip, morph targets, keyframes)."""
import dataclasses
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from lod.full.reps import build_rep
from lod.full import frames as full_frames
from lod.points import deform, follow
from lod.points import mode as pm
from lod.points.follow_select import quantise_frames, quantise_u
from lod.points.rep import HierarchyCache
from lod.points.traverse import _corners
from sim.procedural import humanoid

REPO = Path(__file__).resolve().parents[3]
SHARED = Path(os.environ.get("CROWD_SHARED_ASSETS", REPO.parent / "shared" / "assets"))
sys.path.insert(0, str(REPO / "tests" / "fixtures"))


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return HierarchyCache(tmp_path_factory.mktemp("follow"))


def _rep(ch, cache, **params):
    reps, _ = pm.build([ch], [getattr(ch, "name", "c")], [30], {"animation": "follow", **params}, cache=cache,
                       progress=False)
    assert getattr(reps[0], "follow", False)
    return reps[0]


# ---------------------------------------------------------------------------- kernels and references
def test_pose_kernel_matches_reference_with_morph_targets():
    from tiny_characters import tiny_morphed

    base = build_rep(tiny_morphed(), fps=30, key="m")
    fr = full_frames.SkinnedFrames.of(base)
    rows = np.array([0, 3, fr.n_frames - 1])
    np.testing.assert_allclose(fr.positions(rows), full_frames.pose_positions_numpy(fr, rows), atol=1e-12)
    assert fr.morphs and np.abs(fr.positions(rows) - fr.positions(rows, weight_rows=np.zeros(3, int))).max() > 1e-3


def test_coverage_and_box_kernels_match_references():
    rng = np.random.default_rng(1)
    ch = humanoid(600, 1)
    base = build_rep(ch, fps=30, key="h")
    fr = full_frames.SkinnedFrames.of(base)
    tree = follow.build_follow(fr, base.colors, base.normals, joints=base.joints, weights=base.weights,
                               n_joints=base.joint_table.shape[1])
    h = tree.octree
    # boxes
    tn = follow.triangle_nodes(h)
    ptr, vert = deform.subtree_vertices(np.asarray(h.parent, np.int64), tn, fr.indices, fr.rest.shape[0])
    rows = np.arange(0, fr.n_frames, 5)
    P = fr.positions(rows)
    inv = fr.joint_inverses(rows)[0]
    ref = np.asarray(tree.ref, np.int64)
    lo, hi = np.empty((rows.size, h.n_nodes, 3)), np.empty((rows.size, h.n_nodes, 3))
    deform._box_kernel(ptr, vert, ref, P, inv, lo, hi)
    rlo, rhi = deform.node_boxes_numpy(ptr, vert, ref, P, inv)
    ok = np.isfinite(rlo)
    np.testing.assert_allclose(lo[ok], rlo[ok], atol=1e-12)
    np.testing.assert_allclose(hi[ok], rhi[ok], atol=1e-12)
    # coverage of one node against brute force
    i = 1 if h.child_count[1] and h.point_count[1, 0] else 0
    s, c = int(h.point_start[i, 0]), int(h.point_count[i, 0])
    tri, bary = deform.subtree_triangles(np.asarray(h.parent, np.int64), tn)
    tris = bary[tri[i]:tri[i + 1]]
    from lod.points.sampling import sample_triangles

    pt, pb = sample_triangles(np.ones(tris.size), 50, rng)
    pt = tris[pt]

    def place(Pf, t, b):
        v = Pf[:, fr.indices[t]]
        return (1 - b[:, 0:1] - b[:, 1:2]) * v[:, :, 0] + b[:, 0:1] * v[:, :, 1] + b[:, 1:2] * v[:, :, 2]

    out = np.zeros(1)
    deform._coverage_kernel(np.array([s]), np.array([c]), h.tri.astype(np.int64), h.bary.astype(np.float64),
                            np.array([0]), np.array([pt.size]), pt.astype(np.int64), pb, fr.indices, P,
                            np.array([0.0]), np.full(pt.size, -1, np.int64), out)
    ref_cov = deform.coverage_numpy(place(P, h.tri[s:s + c].astype(int), h.bary[s:s + c].astype(float)),
                                    place(P, pt, pb))
    assert out[0] == pytest.approx(ref_cov, rel=1e-12)


def test_small_kernels_match_their_references():
    """Gram terms, largest areas, posed candidate positions, subtree triangles, the pose choice's farthest pass and
    the K-pose farthest-point order against plain numpy."""
    from lod.points.coarse import farthest_order
    from lod.points.octree import sample_positions_at, sample_positions_posed

    rng = np.random.default_rng(5)
    ch = humanoid(600, 2)
    base = build_rep(ch, fps=30, key="h")
    fr = full_frames.SkinnedFrames.of(base)
    P = fr.positions(np.arange(0, fr.n_frames, 7))
    np.testing.assert_allclose(deform.frame_grams(P, fr.indices), deform.grams(P, fr.indices), rtol=1e-12, atol=1e-15)
    want = np.maximum(0.5 * np.sqrt(np.maximum(deform.grams(fr.positions(np.arange(fr.n_frames)), fr.indices)[..., 3],
                                               0.0)).max(0), 0.5 * np.sqrt(np.maximum(deform.grams(fr.rest, fr.indices)
                                                                                      [:, 3], 0.0)))
    np.testing.assert_allclose(deform.largest_areas(fr), want, rtol=1e-12)
    VK = np.stack([P[k][fr.indices] for k in range(3)])
    tri = rng.integers(0, fr.indices.shape[0], 40)
    b = rng.random((40, 2)) * 0.5
    got = sample_positions_posed(VK, tri, b)
    for k in range(3):
        np.testing.assert_allclose(got[k], sample_positions_at(VK[k], VK[k], tri, b, [0.0])[0], atol=1e-12)
    parent = np.array([-1, 0, 0, 1, 1, 2])
    tn = np.array([3, 4, 4, 5, 0, -1, 2])
    ptr, tris = deform.subtree_triangles(parent, tn)
    sub = {0: {0, 1, 2, 3, 4, 5}, 1: {1, 3, 4}, 2: {2, 5}, 3: {3}, 4: {4}, 5: {5}}
    for i in range(6):
        assert set(tris[ptr[i]:ptr[i + 1]].tolist()) == {t for t in range(7) if tn[t] in sub[i]}
    G = deform.frame_grams(P, fr.indices)
    far = np.full(G.shape[0], np.inf)
    tiny = deform.degenerate_tolerance(fr)
    deform._farthest_kernel(np.ascontiguousarray(G[0]), G, 0.2, tiny, far)
    L = np.sqrt(np.maximum.reduce([G[..., 0], G[..., 2], G[..., 0] + G[..., 2] - 2 * G[..., 1]]))
    ref = 1.0 + np.minimum(deform.stretch_numpy(G[0][None], G, tiny) - 1.0, 2.0 * L / 0.2).max(1)
    np.testing.assert_allclose(far, ref, rtol=1e-12)
    pts = rng.random((3, 30, 3))
    order, radius = farthest_order(None, poses=pts)
    d = np.sqrt(((pts[:, :, None] - pts[:, None]) ** 2).sum(-1)).max(0)
    for m in range(1, 30):  # after m points every point is within radius[m - 1] of one of them
        assert d[:, order[:m]].min(1).max() == pytest.approx(radius[m - 1], rel=1e-12)


def test_k_pose_stratification_matches_the_reference():
    """The witness kernel over K poses (a candidate may go when another covers it at every pose) decides as the
    dense reference does."""
    from lod.points.stratify import stratify, stratify_poses_numpy

    rng = np.random.default_rng(2)
    base = rng.random((400, 3))
    poses = np.stack([base, base * [1.6, 1.0, 1.0], base + 0.1 * np.sin(5 * base)])
    order = rng.permutation(400)
    keep = stratify((1, lambda j: poses), 0.2, order, threads=1)[0]  # one "interval" whose coverage is K poses
    np.testing.assert_array_equal(keep, stratify_poses_numpy(poses, 0.2, order))
    assert keep.sum() > stratify_poses_numpy(poses[:1], 0.2, order).sum()  # more poses keep more
    # two poses are an interval's two ends: the interval reference decides alike
    np.testing.assert_array_equal(stratify(poses[:2], 0.2, order)[0], stratify_poses_numpy(poses[:2], 0.2, order))


def test_traversal_in_joint_frames_matches_the_reference(cache):
    """The instance kernel (numba) reads node boxes in joint frames at fractional frames as the per-instance
    Python reference does."""
    rep = _rep(humanoid(900, 6), cache)
    from lod.points.jobs import traverse_instances, traverse_instances_reference
    from lod.view import Camera

    rng = np.random.default_rng(4)
    v = rep.view(0)
    off, n = int(rep.base.clip_offset[0]), int(rep.base.clip_frames[0])
    for dist in (2.0, 6.0, 25.0):
        cam = Camera.look_at((0.0, 1.5, dist), (0.0, 1.0, 0.0), fov_y=50.0, near=0.05, far=500.0)
        data = np.zeros((12, 16))
        for i in range(12):
            yaw = rng.uniform(0, 6.28)
            m = np.array([[np.cos(yaw), 0, np.sin(yaw)], [0, 1, 0], [-np.sin(yaw), 0, np.cos(yaw)]])
            data[i, :12] = np.hstack([m, (rng.uniform(-2, 2, 3) * [1, 0, 1] - cam.position)[:, None]]).reshape(-1)
            data[i, 12] = off + rng.uniform(0, n - 1)  # fractional rows: the union of both rows' boxes
        got = traverse_instances(v, data, cam.frustum_planes(1.0), 400.0, 2.0)
        ref = traverse_instances_reference(v, data, cam.frustum_planes(1.0), 400.0, 2.0)
        for a, b in zip(got, ref):
            np.testing.assert_array_equal(a, b)


def test_stretch_of_a_known_map():
    """sigma: the largest singular value of the map between a triangle's two poses; a sliver degenerate at the
    reference pose and open at the other gets the cap."""
    p = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    q = p * [3.0, 1.0, 1.0]
    s = deform.stretch_numpy(deform.grams(p, np.array([[0, 1, 2]])), deform.grams(q, np.array([[0, 1, 2]])), 1e-12)
    assert s[0] == pytest.approx(3.0)
    flat = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    s = deform.stretch_numpy(deform.grams(flat, np.array([[0, 1, 2]])), deform.grams(p, np.array([[0, 1, 2]])), 1e-12)
    assert s[0] == deform.STRETCH_CAP


# ---------------------------------------------------------------------------- bounds over time
def _placed(rep, f: float):
    """(vertices (V, 3), samples (P, 3)) posed at fractional baked row f as the GPU places them (matrices and
    morph weights blended between the two rows, then skin ∘ morph; keyframed: segment f's u)."""
    t = rep.tree
    h = t.octree
    idx = np.asarray(h.indices, np.int64)
    if rep.skinned:
        fr = full_frames.SkinnedFrames.of(rep.base)
        F = fr.n_frames
        f0 = int(np.clip(np.floor(f), 0, F - 1))
        f1, a = min(f0 + 1, F - 1), float(f) - f0
        m = (1 - a) * fr.jt[f0].astype(np.float64) + a * fr.jt[f1].astype(np.float64)
        first, count, col, dpos, tw = fr._target_arrays()
        q = fr.rest.copy()
        wts = (1 - a) * tw[f0] + a * tw[f1]
        for v in np.flatnonzero(count):
            e = slice(first[v], first[v] + count[v])
            q[v] += (wts[col[e]][:, None] * dpos[e]).sum(0)
        M = np.einsum("vi,virc->vrc", fr.weights, m[fr.joints])
        P = np.einsum("vrc,vc->vr", M[:, :, :3], q) + M[:, :, 3]
    else:
        seg, u = f
        kf = rep.base
        rows = int(rep.vbase[seg]) + np.arange(int(t.vorder.shape[0]))
        P = (1 - u) * kf.positions0[rows].astype(np.float64) + u * kf.positions1[rows].astype(np.float64)
    b = np.asarray(h.bary, np.float64)
    c = idx[np.asarray(h.tri, np.int64)]
    S = (1 - b[:, 0:1] - b[:, 1:2]) * P[c[:, 0]] + b[:, 0:1] * P[c[:, 1]] + b[:, 1:2] * P[c[:, 2]]
    return P, S


def _node_boxes_at(rep, f):
    """(N, 2, 3) each node's box at frame f as the traversal transforms it (lod/points/traverse.py)."""
    if rep.skinned:
        b = rep.base
        clip = int(np.searchsorted(np.asarray(b.clip_offset), f, side="right") - 1)  # the clip holding row f
        v = rep.view(clip)
        F = v.joint_table.shape[0]
        f0 = int(np.clip(np.floor(f), 0, F - 1))
        f1, a = min(f0 + 1, F - 1), f - f0
        eye = np.hstack([np.eye(3), np.zeros((3, 1))])
        out = []
        for i in range(v.n_nodes):
            mats = () if v.ref[i] < 0 else [v.joint_table[r, v.ref[i]] for r in ((f0, f1) if a > 0 else (f0,))]
            cs = _corners(v.box0[i, 0], v.box0[i, 1], eye, mats)
            out.append([cs.min(0), cs.max(0)])
        return np.array(out)
    seg, u = f
    v = rep.view(seg)
    return v.box_at(u)


def _subtree_members(h):
    """node -> (point indices, vertex indices (original numbering)) of its subtree."""
    tn = follow.triangle_nodes(h)
    ptr, vert = deform.subtree_vertices(np.asarray(h.parent, np.int64), tn, np.asarray(h.indices, np.int64),
                                        int(np.asarray(h.indices).max()) + 1 if h.indices.size else 0)
    pts = []
    for i in range(h.n_nodes):
        sub, k = [i], 0
        while k < len(sub):
            j = sub[k]
            k += 1
            sub += list(range(int(h.child_start[j]), int(h.child_start[j] + h.child_count[j])))
        pts.append(np.flatnonzero(np.isin(h.node, sub)))
    return [(pts[i], vert[ptr[i]:ptr[i + 1]]) for i in range(h.n_nodes)]


def assert_bounds_hold(rep, name=""):
    """Every node's box contains its subtree's samples and vertices at every 30 Hz sample of every clip."""
    h = rep.tree.octree
    members = _subtree_members(h)
    ext = float(np.ptp(h.pos0, axis=0).max()) if h.n_points else 1.0
    tol = 1e-5 * max(ext, 1e-6)
    if rep.skinned:
        b = rep.base
        frames = []
        for c in range(len(b.clip_names)):
            n = int(np.ceil(float(b.clip_duration[c]) * 30.0 - 1e-9)) + 1
            frames += list(b.frame_coordinate(np.full(n, c), np.arange(n) / 30.0))
    else:
        kf = rep.base
        frames = []
        for c in range(kf.n_clips):
            n = int(np.ceil(float(kf.anim_duration[c]) * 30.0 - 1e-9)) + 1
            seg, u = kf.locate(c, kf.anim_t0[c] + np.arange(n) / 30.0)
            frames += list(zip(seg.tolist(), u.tolist()))
    assert frames
    for f in frames:
        P, S = _placed(rep, f)
        boxes = _node_boxes_at(rep, f)
        for i, (pi, vi) in enumerate(members):
            for X in (S[pi], P[vi]):
                if X.size:
                    assert (X >= boxes[i, 0] - tol).all() and (X <= boxes[i, 1] + tol).all(), (name, f, i)


def _generated_corpus(tmp):
    sys.path.insert(0, str(REPO / "scripts"))
    from corpus_models import write_models

    from crowd.characters import build_character
    from crowd.scene import CharacterSpec

    out = []
    for p in write_models(tmp):
        if p.name.startswith("refused_"):
            continue
        spec = CharacterSpec(name=p.stem, generator=None, file=p, triangles=None, seed=0, scale=1.0, fps=30)
        out.append((p.name, build_character(spec)))
    return out


def test_bounds_hold_at_every_30hz_sample_of_the_generated_corpus(tmp_path, cache):
    """scripts/corpus_models.py: mixed rig (rigid parts on animated joints, weights summing to 1.8), a statue
    without clip, a 100-joint chain, 64 primitives, 0.1 s and 60 s clips, skin and morph targets, a humanoid and a
    keyframed quadruped (one triangle list: it follows when asked)."""
    for name, ch in _generated_corpus(tmp_path):
        rep = _rep(ch, cache)
        assert_bounds_hold(rep, name)


@pytest.mark.skipif(not SHARED.is_dir(), reason=f"no shared assets at {SHARED} (CROWD_SHARED_ASSETS names them)")
def test_bounds_hold_at_every_30hz_sample_of_the_shared_assets(cache):
    from crowd.characters import build_character
    from crowd.scene import CharacterSpec

    for p in sorted(SHARED.glob("*.glb")):
        ch = build_character(CharacterSpec(name=p.stem, generator=None, file=p, triangles=None, seed=0, scale=1.0,
                                           fps=30))
        assert_bounds_hold(_rep(ch, cache), p.name)


def test_degenerate_triangles_and_unnormalised_weights(cache):
    """Triangles with repeated corners (zero area in every pose) and weights summing to 1.7 (normalised by the
    full-detail rep the samples follow): the hierarchy builds, its numbers are finite, no sample lies on a
    degenerate triangle, and the bounds hold at every 30 Hz sample."""
    ch = humanoid(700, 8)
    idx = np.array(ch.mesh.indices, np.int64)
    idx[::25, 1] = idx[::25, 0]  # [a, a, c]: zero area
    idx[3::50] = idx[3::50, :1]  # [a, a, a]
    m = dataclasses.replace(ch.mesh, indices=idx.astype(np.uint32), weights=np.asarray(ch.mesh.weights) * 1.7,
                            normals=None)
    ch = dataclasses.replace(ch, mesh=m)
    rep = _rep(ch, cache)
    t = rep.tree
    for k, v in list(t.__dict__.items()) + list(t.octree.__dict__.items()):
        if isinstance(v, np.ndarray) and v.dtype.kind == "f":
            assert np.isfinite(v).all(), k
    bad = np.flatnonzero((idx[:, 0] == idx[:, 1]) | (idx[:, 1] == idx[:, 2]) | (idx[:, 0] == idx[:, 2]))
    assert not np.isin(t.octree.tri, bad).any()
    assert_bounds_hold(rep, "degenerate")


# ---------------------------------------------------------------------------- spacing under deformation
def stretching_joint(stretch: float = 2.5):
    """A tube of two joints whose upper joint scales ``stretch``-fold along the tube in its looping clip."""
    from sim.character import SkinnedCharacter
    from sim.clip import Channel, Clip
    from sim.mesh import Mesh
    from sim.skeleton import Skeleton

    rings, sides = 25, 16
    ang = np.linspace(0, 2 * np.pi, sides, endpoint=False)
    y = np.linspace(0.0, 2.0, rings)
    pos = np.array([[0.15 * np.cos(a), yy, 0.15 * np.sin(a)] for yy in y for a in ang], np.float32)
    idx = []
    for r in range(rings - 1):
        for s in range(sides):
            a, b = r * sides + s, r * sides + (s + 1) % sides
            idx += [[a, a + sides, b], [b, a + sides, b + sides]]
    wt = np.clip((pos[:, 1] - 0.6) / 0.8, 0.0, 1.0)  # bottom on joint 0, top on joint 1, blended around 1 m
    joints = np.zeros((pos.shape[0], 4), np.uint16)
    joints[:, 1] = 1
    weights = np.zeros((pos.shape[0], 4), np.float32)
    weights[:, 0], weights[:, 1] = 1.0 - wt, wt
    mesh = Mesh(pos, np.array(idx, np.uint32), joints=joints, weights=weights,
                colors=np.tile([0.8, 0.3, 0.2, 1.0], (pos.shape[0], 1)).astype(np.float32))
    mesh.ensure_normals()
    sk = Skeleton(names=["root", "upper"], parents=np.array([-1, 0], np.int32),
                  rest_translation=np.array([[0.0, 0, 0], [0, 1.0, 0]]), rest_rotation=np.array([[0, 0, 0, 1.0]] * 2),
                  rest_scale=np.ones((2, 3)), inverse_bind=np.tile(np.eye(4), (2, 1, 1)))
    sk.inverse_bind = sk.rest_inverse_bind()
    t = np.linspace(0.0, 2.0, 31)
    sc = np.stack([np.ones_like(t), 1.0 + (stretch - 1.0) * 0.5 * (1 - np.cos(np.pi * t)), np.ones_like(t)], 1)
    clip = Clip("stretch", 2.0, [Channel(1, "scale", t, sc)], loop=True)
    return SkinnedCharacter("stretchy", mesh, sk, {"stretch": clip})


def _follow_rep(ch, max_poses: int):
    base = build_rep(ch, fps=30, key="points:s")
    fr = full_frames.SkinnedFrames.of(base)
    tree = follow.build_follow(fr, base.colors, base.normals, joints=base.joints, weights=base.weights,
                               n_joints=base.joint_table.shape[1], max_poses=max_poses)
    return follow.FollowRep("points:s", base, tree)


def _worst_gap(rep, f, splat: float = 2.0, probes: int = 40_000) -> list:
    """Per camera distance at which the traversal draws points: the largest distance on screen (pixels) from a
    surface point at baked row f to the nearest sample of the nodes drawn as points whose subtrees hold it."""
    from scipy.spatial import cKDTree

    from lod.points.jobs import traverse_instances
    from lod.points.sampling import sample_triangles
    from lod.points.traverse import viewport_scale
    from lod.view import Camera

    P, S = _placed(rep, f)
    h = rep.tree.octree
    idx = np.asarray(h.indices, np.int64)
    a = 0.5 * np.linalg.norm(np.cross(P[idx[:, 1]] - P[idx[:, 0]], P[idx[:, 2]] - P[idx[:, 0]]), axis=1)
    t, b = sample_triangles(a, probes, np.random.default_rng(3))
    c = idx[t]
    q = (1 - b[:, 0:1] - b[:, 1:2]) * P[c[:, 0]] + b[:, 0:1] * P[c[:, 1]] + b[:, 1:2] * P[c[:, 2]]
    tn = follow.triangle_nodes(h)
    vs = viewport_scale(320, 40.0)
    out = []
    for dist in (8.0, 12.0, 18.0, 27.0, 40.0, 60.0, 90.0):
        cam = Camera.look_at((dist, 1.2, 0.0), (0.0, 1.2, 0.0), fov_y=40.0, near=0.05, far=200.0)
        data = np.zeros((1, 16))
        data[0, :12] = np.hstack([np.eye(3), -np.asarray(cam.position)[:, None]]).reshape(-1)
        data[0, 12] = f
        pj, _ = traverse_instances(rep.view(0), data, cam.frustum_planes(1.0), vs, splat)
        worst = 0.0
        for _, s, n in pj.tolist():  # each node drawn as points against the surface it stands for
            i = int(h.node[s])
            sub, k = [i], 0
            while k < len(sub):
                j = sub[k]
                k += 1
                sub += list(range(int(h.child_start[j]), int(h.child_start[j] + h.child_count[j])))
            mine = np.isin(tn[t], sub)
            if mine.any():
                d, _ = cKDTree(S[s:s + n]).query(q[mine])
                worst = max(worst, float((d / np.abs(q[mine, 0] - dist) * vs).max()))
        if pj.size:
            out.append((dist, worst))
    return out


def test_no_hole_larger_than_the_splat_on_a_stretching_joint():
    """A joint stretching 2.5x: at its most stretched frame every point of the surface lies within half a splat
    (on screen) of a sample of the node drawn as points that stands for it, at every distance the traversal
    draws points. Both ways of keeping that: the default stratifies over poses that include the stretched one;
    stratified at one pose only, the nodes' measured growth (``stretch`` > 1) makes the traversal refine."""
    ch = stretching_joint(2.5)
    splat = 2.0
    for max_poses in (deform_default(), 1):
        rep = _follow_rep(ch, max_poses)
        f = float(rep.base.frame_coordinate(np.array([0]), np.array([1.0]))[0])  # the most stretched frame
        if max_poses == 1:
            assert rep.tree.stretch.max() > 1.2  # the growth is measured ...
        gaps = _worst_gap(rep, f, splat)
        assert len(gaps) >= 3
        for dist, px in gaps:  # ... and no gap exceeds the splat
            assert px <= 0.5 * splat * 1.1, (max_poses, dist, px)


def deform_default() -> int:
    return follow.STRATIFY_POSES


def test_holes_appear_without_the_measured_growth():
    """The test above can fail: stratified at one pose and with the nodes' growth ignored (stretch 1, the
    octree's own spacing), the stretched joint opens gaps wider than the splat."""
    rep = _follow_rep(stretching_joint(2.5), 1)
    rep.tree.stretch = np.ones_like(rep.tree.stretch)
    f = float(rep.base.frame_coordinate(np.array([0]), np.array([1.0]))[0])
    assert max(px for _, px in _worst_gap(rep, f)) > 1.5


# ---------------------------------------------------------------------------- prefixes, memory, cache, poses
def test_prefixes_hold_what_the_nodes_up_to_each_need(cache):
    rep = _rep(humanoid(800, 2), cache)
    t = rep.tree
    h = t.octree
    for i in range(h.n_nodes):
        s, n = int(h.point_start[i, 0]), int(h.point_count[i, 0])
        assert s + n <= t.pprefix[i]
        used = t.corners[np.asarray(h.tri[s:s + n], np.int64)]
        tri = h.tri_order[int(h.tri_start[i]):int(h.tri_start[i] + h.tri_count[i])]
        used = np.concatenate([used.reshape(-1), t.corners[np.asarray(tri, np.int64)].reshape(-1)])
        assert used.size == 0 or used.max() < t.vprefix[i]
    assert (np.diff(t.vprefix) >= 0).all() and (np.diff(t.pprefix) >= 0).all()
    assert np.array_equal(np.sort(t.vorder), np.arange(t.vorder.size))


def test_memory_does_not_grow_with_the_clip(cache):
    from sim.dance import dance_clip

    base = humanoid(800, 3)
    short = dataclasses.replace(base, clips={"dance": dance_clip(base, 2.0, seed=1)})
    long = dataclasses.replace(base, clips={"dance": dance_clip(base, 40.0, seed=1)})
    a, b = _rep(short, cache).nbytes, _rep(long, cache).nbytes
    assert b <= 1.3 * a, (a, b)
    assert pm.memory_estimate([long], {}) == pm.memory_estimate([short], {})


def test_cache_round_trip_and_corruption(tmp_path):
    ch = humanoid(500, 4)
    c1 = HierarchyCache(tmp_path / "c")
    a = _rep(ch, c1)
    assert c1.misses == 1
    c2 = HierarchyCache(tmp_path / "c")
    b = _rep(ch, c2)
    assert c2.hits == 1
    for k, v in a.tree.__dict__.items():
        if isinstance(v, np.ndarray):
            np.testing.assert_array_equal(v, getattr(b.tree, k))
    for k, v in a.tree.octree.__dict__.items():
        if isinstance(v, np.ndarray) and not k.startswith("_"):
            np.testing.assert_array_equal(v, getattr(b.tree.octree, k))
    npz = next((tmp_path / "c").glob("follow-*.npz"))
    npz.write_bytes(npz.read_bytes()[:100])
    c3 = HierarchyCache(tmp_path / "c")
    _rep(ch, c3)
    assert c3.misses == 1 and c3.hits == 0


def test_pose_quantisation():
    ch = humanoid(500, 4)
    base = build_rep(ch, fps=30, key="h")
    off, n = int(base.clip_offset[0]), int(base.clip_frames[0])
    f = off + np.array([0.2, 0.6, n - 1.6, n - 1.2])
    q = quantise_frames(base, 0, f)
    assert q.tolist() == [off, off + 1, off + n - 2, off]  # rounded to rows; a looping clip's end is its start
    assert np.array_equal(quantise_frames(base, 0, f, 0.0), f)  # exact
    q15 = quantise_frames(base, 0, off + np.array([0.9, 1.1]), 15.0)  # every other row
    assert q15.tolist() == pytest.approx([off, off + 2])


def test_keyframed_paths():
    """One triangle list over the segments: short flip-books stay baked under auto, follow when asked; a
    keyframe animation that changes triangles is only ever baked."""
    from tiny_characters import tiny_keyframed

    from lod.points.paths import animation_path

    from sim.procedural import quadruped

    flag = tiny_keyframed()  # a triangle appears between its keyframes (Wand & Strasser Fig. 1)
    assert animation_path(flag, {"animation": "auto"})[0] == "baked"
    with pytest.raises(ValueError, match="changes triangles"):
        animation_path(flag, {"animation": "follow"})
    book = pm.keyframed_character(quadruped(600, seed=2), 5)  # a flip-book: one triangle list
    assert animation_path(book, {})[0] == "baked"
    assert animation_path(book, {"animation": "follow"})[0] == "follow"
    assert animation_path(humanoid(500, 1), {})[0] == "follow"
    kf = build_rep(book, key="k")
    assert quantise_u(kf, 0, np.array([0.01, 0.5]), 0.0).tolist() == [0.01, 0.5]
    dur = float(kf.seg_end[0] - kf.seg_start[0])
    n = max(1.0, round(dur * 30.0))  # about 30 poses a second: the segment cut in n equal steps
    q = quantise_u(kf, 0, np.array([0.01, 0.5]))
    assert np.allclose(q * n, np.round(q * n)) and np.abs(q - [0.01, 0.5]).max() <= 0.5 / n + 1e-12


def test_distinct_poses_are_np_unique_of_them():
    """follow_batch's distinct poses (a presence table over whole numbers or float32 bit patterns) equal
    np.unique's values and inverse, on quantised frames, exact frames, zeros, one value, and inputs that take the
    sort (negative, NaN, -0, values beyond the table)."""
    from lod.points.follow_select import DISTINCT_TABLE, _distinct

    rng = np.random.default_rng(2)
    cases = [np.floor(rng.uniform(0, 300, 5000)).astype(np.float32), rng.uniform(0, 40, 3000).astype(np.float32),
             np.zeros(7, np.float32), np.array([3.5], np.float32), np.zeros(0, np.float32),
             np.array([-1.0, 2.0, -1.0], np.float32), np.array([1.0, np.nan, 1.0], np.float32),
             np.array([1e-30, 1e30, 1e-30], np.float32), np.array([0.0, 1000.0, 12.0, 0.0], np.float32),
             np.array([0.0, -0.0, 2.0], np.float32), (np.arange(10) * 0.25 + 100.0).astype(np.float32)]
    for c in cases:
        q = c.astype(np.float64)
        pose, slot = _distinct(q)
        want_pose, want_slot = np.unique(q, return_inverse=True)
        np.testing.assert_array_equal(pose, want_pose)
        np.testing.assert_array_equal(slot, want_slot.reshape(-1))
    assert DISTINCT_TABLE >= 1 << 16
