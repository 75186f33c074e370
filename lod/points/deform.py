"""How a character's surface moves over its animation: the measurements mode points needs to draw
samples taken once, in one pose, with the animation (``lod.points.follow``; Wand & Straßer 2002 §3.3
and §3.4 generalised from one keyframe pair to a whole character).

Frames and posed vertex positions: ``lod.full.frames`` (:class:`~lod.full.frames.SkinnedFrames`,
:class:`~lod.full.frames.KeyframedFrames`). Between two
rows the GPU blends linearly, so a vertex lies on the chord of its positions at the rows (with morph targets
on a quadratic curve near it, ``lod.full.targets``).

Measurements, streamed over the frames in chunks (never a (frames, vertices) array):

* :func:`largest_areas`: each triangle's largest area over the frames: the sampling weights (§3.4.1: "the
  maximum area that it will have").
* Stratification poses (:func:`choose_poses`). The samples are stratified so that every candidate is within
  r/2 of a kept sample at each of K poses (§3.4.2 with K poses in place of an interval's two ends). They are
  chosen farthest-first (k-centre) in stretch: at frame s a triangle is the affine image of itself at pose k,
  and distances on it grow by at most the largest singular value sigma of that map (:func:`stretch_numpy`: the
  square root of the largest eigenvalue of ``G_k^-1 G_s``, G the Gram matrix of two edges), and by at most its
  longest edge (a sliver opening in its thin direction adds its own size, not sigma times the spacing's);
  start at the first frame, add the frame farthest from the chosen ones, until that is at most ``target`` or
  K poses are chosen.
* Coverage (:func:`node_coverage`): per node the largest distance, at every frame, from a probe on its
  subtree's surface to the nearest of its samples (witnesses kept from frame to frame, searched again only
  when farther than r/2): the traversal's spacing factor (``lod.points.follow``).
* :func:`node_boxes`: per node an axis-aligned box in the frame of one joint (``ref``; -1: the model frame)
  holding the node's subtree vertices at every frame: the box at a frame is its corners through the joint's
  skinning matrix of that row (VDR-AM keeps its cluster bounds relative to the deforming joint likewise).
  Samples are barycentric combinations of their triangle's vertices, and the frame change is affine, so
  the box holds every sample of the node at every frame.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from lod.full.frames import FRAME_CHUNK, KeyframedFrames, chunks, row_chunks

#: cap on a triangle's stretch (a triangle degenerate at a pose it is mapped from)
STRETCH_CAP = 64.0
#: triangles the pose choice measures (evenly strided; their Gram terms at every frame are kept: 16 B each)
CHOICE_TRIANGLES = 2048
#: a triangle whose doubled squared area at a pose is below this fraction of the largest is degenerate there
DEGENERATE = 1e-14


# ---------------------------------------------------------------------------- areas and stretch
def grams(p: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """(..., T, 4) float64 (g11, g12, g22, det) of the edge Gram matrices of triangles ``idx`` at positions
    ``p`` (..., V, 3): edges e1 = p1 - p0, e2 = p2 - p0; det = 4 area^2."""
    a = p[..., idx[:, 0], :]
    e1 = p[..., idx[:, 1], :] - a
    e2 = p[..., idx[:, 2], :] - a
    g11 = (e1 * e1).sum(-1)
    g12 = (e1 * e2).sum(-1)
    g22 = (e2 * e2).sum(-1)
    return np.stack([g11, g12, g22, g11 * g22 - g12 * g12], axis=-1)


def stretch_numpy(gk: np.ndarray, gs: np.ndarray, tiny: float) -> np.ndarray:
    """Largest singular value of the map taking each triangle at pose k to itself at pose s.

    gk, gs : (..., 4) :func:`grams` at both poses; tiny : a det below it is degenerate.
    sigma^2 is the largest root of ``det(Gs - l Gk) = 0``; a triangle degenerate at k but not at s gets
    :data:`STRETCH_CAP`, one degenerate at both 0 (it holds no surface)."""
    dk, ds = gk[..., 3], gs[..., 3]
    b = gk[..., 0] * gs[..., 2] + gk[..., 2] * gs[..., 0] - 2.0 * gk[..., 1] * gs[..., 1]
    ok = dk > tiny
    lam = (b + np.sqrt(np.maximum(b * b - 4.0 * dk * ds, 0.0))) / (2.0 * np.where(ok, dk, 1.0))
    sig = np.sqrt(np.maximum(lam, 0.0))
    sig = np.where(ok, np.minimum(sig, STRETCH_CAP), np.where(ds > tiny, STRETCH_CAP, 0.0))
    return np.where(np.isfinite(sig), sig, STRETCH_CAP)


@njit(cache=True, inline="always")
def _stretch(k11, k12, k22, kd, s11, s12, s22, sd, tiny):  # pragma: no cover - compiled
    if kd <= tiny:
        return STRETCH_CAP if sd > tiny else 0.0
    b = k11 * s22 + k22 * s11 - 2.0 * k12 * s12
    disc = b * b - 4.0 * kd * sd
    lam = (b + np.sqrt(max(disc, 0.0))) / (2.0 * kd)
    s = np.sqrt(max(lam, 0.0))
    if not (s < STRETCH_CAP):  # also NaN
        return STRETCH_CAP
    return s


@njit(cache=True, inline="always")
def _gram(posed, f, idx, t):  # pragma: no cover - compiled
    """(g11, g12, g22) of triangle t at frame f of ``posed`` (:func:`grams`)."""
    a = idx[t, 0]
    b = idx[t, 1]
    c = idx[t, 2]
    ex = posed[f, b, 0] - posed[f, a, 0]
    ey = posed[f, b, 1] - posed[f, a, 1]
    ez = posed[f, b, 2] - posed[f, a, 2]
    gx = posed[f, c, 0] - posed[f, a, 0]
    gy = posed[f, c, 1] - posed[f, a, 1]
    gz = posed[f, c, 2] - posed[f, a, 2]
    return ex * ex + ey * ey + ez * ez, ex * gx + ey * gy + ez * gz, gx * gx + gy * gy + gz * gz


@njit(cache=True, parallel=True)
def _grams_kernel(posed, idx, out):  # pragma: no cover - compiled
    """out (n, T, 4): :func:`grams` of every frame of ``posed`` (n, V, 3)."""
    for f in prange(posed.shape[0]):
        for t in range(idx.shape[0]):
            g11, g12, g22 = _gram(posed, f, idx, t)
            out[f, t, 0] = g11
            out[f, t, 1] = g12
            out[f, t, 2] = g22
            out[f, t, 3] = g11 * g22 - g12 * g12


def frame_grams(posed, idx) -> np.ndarray:
    """(n, T, 4) float64 :func:`grams` of frames ``posed`` (n, V, 3) (numba; :func:`grams` is the reference)."""
    posed = np.ascontiguousarray(posed, np.float64)
    out = np.empty((posed.shape[0], np.asarray(idx).shape[0], 4))
    if out.size:
        _grams_kernel(posed, np.ascontiguousarray(idx, np.int64), out)
    return out


@njit(cache=True, parallel=True)
def _area_kernel(posed, idx, best):  # pragma: no cover - compiled
    """best[t] = max(best[t], the triangle's area at every frame of ``posed``)."""
    for t in prange(idx.shape[0]):
        for f in range(posed.shape[0]):
            g11, g12, g22 = _gram(posed, f, idx, t)
            area = 0.5 * np.sqrt(max(g11 * g22 - g12 * g12, 0.0))
            if area > best[t]:
                best[t] = area


def largest_areas(frames, chunk: int = FRAME_CHUNK) -> np.ndarray:
    """(T,) float64 each triangle's largest area over every frame (and the rest pose)."""
    idx = np.ascontiguousarray(frames.indices, np.int64)
    best = 0.5 * np.sqrt(np.maximum(grams(frames.rest, idx)[:, 3], 0.0))
    for a, b in chunks(frames.n_frames, chunk):
        _area_kernel(frames.positions(np.arange(a, b)), idx, best)
    return best


@njit(cache=True, parallel=True)
def _farthest_kernel(gk, G, scale, tiny, far):  # pragma: no cover - compiled
    """far[f] = min(far[f], 1 + max_t min(sigma_t(k -> f) - 1, 2 L_t(f) / scale)) (:func:`choose_poses`)."""
    for f in prange(G.shape[0]):
        worst = 0.0
        for t in range(G.shape[1]):
            s11 = G[f, t, 0]
            s12 = G[f, t, 1]
            s22 = G[f, t, 2]
            s = _stretch(gk[t, 0], gk[t, 1], gk[t, 2], gk[t, 3], s11, s12, s22, G[f, t, 3], tiny) - 1.0
            L2 = max(s11, s22, s11 + s22 - 2.0 * s12)
            v = min(s, 2.0 * np.sqrt(max(L2, 0.0)) / scale)
            if v > worst:
                worst = v
        if 1.0 + worst < far[f]:
            far[f] = 1.0 + worst


def degenerate_tolerance(frames) -> float:
    """The det (4 area^2) below which a triangle counts as degenerate (relative to the rest pose's largest)."""
    g = grams(frames.rest, frames.indices)[:, 3]
    top = float(g.max()) if g.size else 0.0
    return max(DEGENERATE * top, 1e-300)


def choose_poses(frames, count: int, target: float, scale: float, triangles: int = CHOICE_TRIANGLES,
                 chunk: int = FRAME_CHUNK) -> tuple[np.ndarray, float]:
    """The stratification poses: (rows (K,) int64, the largest stretch left, measured on a strided subset
    of ``triangles`` triangles at the spacing ``scale``, as :func:`node_stretch` measures a node of that
    spacing). Farthest-first: the first frame, then repeatedly the frame whose stretch from its nearest
    chosen pose is largest, until that is at most ``target`` or ``count`` poses are chosen."""
    F = frames.n_frames
    if F == 0:
        return np.zeros(0, np.int64), 1.0
    idx_all = frames.indices
    sub = np.unique(np.linspace(0, idx_all.shape[0] - 1, min(triangles, idx_all.shape[0])).astype(np.int64)) \
        if idx_all.shape[0] else np.zeros(0, np.int64)
    tri = idx_all[sub]
    verts, local = np.unique(tri.reshape(-1), return_inverse=True)
    local = local.reshape(-1, 3)
    G = np.empty((F, sub.shape[0], 4), np.float32)  # the subset's Gram terms at every frame (16 B a triangle)
    for a, b in chunks(F, chunk):
        G[a:b] = frame_grams(frames.positions(np.arange(a, b), verts), local)
    tiny = degenerate_tolerance(frames)
    far = np.full(F, np.inf)
    rows = [0]
    while True:
        if sub.size:
            _farthest_kernel(np.ascontiguousarray(G[rows[-1]], np.float64), G, max(float(scale), 1e-300), tiny, far)
        else:
            far[:] = 1.0
        worst = int(np.argmax(far))
        if far[worst] <= target or len(rows) >= count or worst in rows:
            return np.array(rows, np.int64), float(max(far[worst], 1.0))
        rows.append(worst)


# ---------------------------------------------------------------------------- coverage
@njit(cache=True)
def subtree_triangles(parent, tri_node):  # pragma: no cover - compiled
    """CSR (ptr (N + 1,), tri) of the triangles stored in each node's subtree (node i's points stand for them)."""
    N = parent.shape[0]
    T = tri_node.shape[0]
    depth = np.zeros(N, np.int64)
    for i in range(1, N):
        depth[i] = depth[parent[i]] + 1
    cnt = np.zeros(N + 1, np.int64)
    for t in range(T):
        i = tri_node[t]
        while i >= 0:
            cnt[i + 1] += 1
            i = parent[i]
    for i in range(N):
        cnt[i + 1] += cnt[i]
    out = np.empty(cnt[N], np.int64)
    fill = cnt[:-1].copy()
    for t in range(T):
        i = tri_node[t]
        while i >= 0:
            out[fill[i]] = t
            fill[i] += 1
            i = parent[i]
    return cnt, out


@njit(cache=True, inline="always")
def _place(P, f, idx, t, b1, b2, out, r):  # pragma: no cover - compiled
    b0 = 1.0 - b1 - b2
    a = idx[t, 0]
    b = idx[t, 1]
    c = idx[t, 2]
    for k in range(3):
        out[r, k] = b0 * P[f, a, k] + b1 * P[f, b, k] + b2 * P[f, c, k]


@njit(cache=True, parallel=True)
def _coverage_kernel(kstart, kcount, ktri, kbary, pstart, pcount, ptri, pbary, idx, posed, tau, wit,
                     out):  # pragma: no cover - compiled
    """Per node q (parallel): at every frame of ``posed`` the largest distance from one of its probes to the
    nearest of its kept samples, into out[q] (max). ``wit``: each probe's witness (a kept sample, local
    index; -1 none), kept over the frames: a probe is searched again only when its witness is farther than
    ``tau[q]``, so the distances recorded are exact wherever they exceed it."""
    for q in prange(kstart.shape[0]):
        c = kcount[q]
        if c == 0 or pcount[q] == 0:
            continue
        kp = np.empty((c, 3))
        pp = np.empty((1, 3))
        t2 = tau[q] * tau[q]
        best_all = out[q] * out[q]
        for f in range(posed.shape[0]):
            for e in range(c):
                s = kstart[q] + e
                _place(posed, f, idx, ktri[s], kbary[s, 0], kbary[s, 1], kp, e)
            for e in range(pstart[q], pstart[q] + pcount[q]):
                _place(posed, f, idx, ptri[e], pbary[e, 0], pbary[e, 1], pp, 0)
                w = wit[e]
                d2 = np.inf
                if w >= 0:
                    d2 = (pp[0, 0] - kp[w, 0]) ** 2 + (pp[0, 1] - kp[w, 1]) ** 2 + (pp[0, 2] - kp[w, 2]) ** 2
                if d2 > t2:
                    for g in range(c):
                        x = (pp[0, 0] - kp[g, 0]) ** 2 + (pp[0, 1] - kp[g, 1]) ** 2 + (pp[0, 2] - kp[g, 2]) ** 2
                        if x < d2:
                            d2 = x
                            w = g
                    wit[e] = w
                if d2 > best_all:
                    best_all = d2
        out[q] = np.sqrt(best_all)


def coverage_numpy(kpos, ppos) -> float:
    """Reference: the largest distance from a probe (f, m, 3) to its nearest kept sample (f, c, 3) over
    the frames."""
    d = np.sqrt(((np.asarray(ppos)[:, :, None, :] - np.asarray(kpos)[:, None, :, :]) ** 2).sum(-1))
    return float(d.min(2).max()) if d.size else 0.0


def node_coverage(frames, h, probes: float, rng, chunk: int = FRAME_CHUNK, weights=None, rows=None) -> np.ndarray:
    """(N,) float64: per node the largest distance, over every frame, from a probe on its subtree's surface to
    the nearest of its samples (0 for nodes without samples). ``probes`` per sample (at least 8 a node) are
    drawn by ``weights`` (each triangle's largest area) on the triangles of the node's subtree and placed with
    the animation as the samples are. This is the covering radius §3.4.2 guarantees at an interval's ends
    (r/2 for the candidates), measured at every frame (of ``rows``: one clip's) instead of constructed at two."""
    from lod.points.sampling import sample_triangles

    N = h.n_nodes
    out = np.zeros(N)
    idx = np.asarray(h.indices, np.int64)
    tri_node = np.full(idx.shape[0], -1, np.int64)
    for i in np.flatnonzero(h.tri_count > 0).tolist():
        s, c = int(h.tri_start[i]), int(h.tri_count[i])
        tri_node[h.tri_order[s:s + c]] = i
    tptr, ttri = subtree_triangles(np.asarray(h.parent, np.int64), tri_node)
    w = np.asarray(weights, np.float64) if weights is not None else np.ones(idx.shape[0])
    nodes = [i for i in range(N) if h.child_count[i] > 0 and h.point_count[i, 0] > 0]
    if not nodes or frames.n_frames == 0:
        return out
    kstart = np.array([h.point_start[i, 0] for i in nodes], np.int64)
    kcount = np.array([h.point_count[i, 0] for i in nodes], np.int64)
    pt, pb, pc = [], [], []
    for i, c in zip(nodes, kcount.tolist()):
        tris = ttri[tptr[i]:tptr[i + 1]]
        m = max(8, int(np.ceil(probes * c)))
        t, b = sample_triangles(w[tris], m, rng)
        pt.append(tris[t])
        pb.append(b)
        pc.append(t.shape[0])
    pcount = np.asarray(pc, np.int64)
    pstart = np.concatenate([[0], np.cumsum(pcount)[:-1]]).astype(np.int64)
    ptri = np.concatenate(pt).astype(np.int64)
    pbary = np.concatenate(pb).astype(np.float64)
    tau = 0.5 * np.asarray(h.spacing, np.float64)[nodes]
    wit = np.full(ptri.shape[0], -1, np.int64)
    res = np.zeros(len(nodes))
    ktri = np.ascontiguousarray(h.tri, np.int64)
    kbary = np.ascontiguousarray(h.bary, np.float64)
    for r in row_chunks(frames, rows, chunk):
        _coverage_kernel(kstart, kcount, ktri, kbary, pstart, pcount, ptri, pbary, idx, frames.positions(r), tau,
                         wit, res)
    out[nodes] = res
    return out


# ---------------------------------------------------------------------------- node boxes
@njit(cache=True)
def subtree_vertices(parent, tri_node, idx, V):  # pragma: no cover - compiled
    """CSR (ptr (N + 1,), vert) of the distinct vertices of the triangles in each node's subtree."""
    N = parent.shape[0]
    # a node's own triangles, CSR
    cnt = np.zeros(N + 1, np.int64)
    for t in range(tri_node.shape[0]):
        if tri_node[t] >= 0:
            cnt[tri_node[t] + 1] += 1
    for i in range(N):
        cnt[i + 1] += cnt[i]
    own = np.empty(cnt[N], np.int64)
    fill = cnt[:-1].copy()
    for t in range(tri_node.shape[0]):
        i = tri_node[t]
        if i >= 0:
            own[fill[i]] = t
            fill[i] += 1
    # children lists (breadth-first: contiguous, but use parent for generality)
    kids = np.zeros(N + 1, np.int64)
    for i in range(1, N):
        kids[parent[i] + 1] += 1
    for i in range(N):
        kids[i + 1] += kids[i]
    child = np.empty(max(N - 1, 0), np.int64)
    kf = kids[:-1].copy()
    for i in range(1, N):
        p = parent[i]
        child[kf[p]] = i
        kf[p] += 1
    stamp = np.full(V, -1, np.int64)
    ptr = np.zeros(N + 1, np.int64)
    out = np.empty(16, np.int64)
    n = 0
    stack = np.empty(N + 1, np.int64)
    for i in range(N):
        sp = 0
        stack[sp] = i
        sp += 1
        while sp > 0:
            sp -= 1
            q = stack[sp]
            for e in range(cnt[q], cnt[q + 1]):
                t = own[e]
                for c in range(3):
                    v = idx[t, c]
                    if stamp[v] != i:
                        stamp[v] = i
                        if n == out.shape[0]:
                            grown = np.empty(2 * n, np.int64)
                            grown[:n] = out
                            out = grown
                        out[n] = v
                        n += 1
            for e in range(kids[q], kids[q + 1]):
                stack[sp] = child[e]
                sp += 1
        ptr[i + 1] = n
    return ptr, out[:n]


def reference_joints(ptr, vert, joints, weights, n_joints: int) -> np.ndarray:
    """(N,) int32 per node the joint carrying the largest total skin weight of its vertices."""
    N = ptr.shape[0] - 1
    out = np.zeros(N, np.int32)
    for i in range(N):
        v = vert[ptr[i]:ptr[i + 1]]
        if not v.size:
            continue
        tot = np.bincount(joints[v].reshape(-1), weights=weights[v].reshape(-1), minlength=n_joints)
        out[i] = int(np.argmax(tot))
    return out


@njit(cache=True, parallel=True)
def _box_kernel(ptr, vert, ref, posed, inv, lo, hi):  # pragma: no cover - compiled
    """lo/hi (n, N, 3): per frame the box of each node's vertices in its joint's frame (inv (n, J, 3, 4));
    ref -1: the model frame; ref -2: skipped."""
    N = ptr.shape[0] - 1
    for f in prange(posed.shape[0]):
        for i in range(N):
            j = ref[i]
            for c in range(3):
                lo[f, i, c] = np.inf
                hi[f, i, c] = -np.inf
            if j < -1:
                continue
            for e in range(ptr[i], ptr[i + 1]):
                v = vert[e]
                x = posed[f, v, 0]
                y = posed[f, v, 1]
                z = posed[f, v, 2]
                for c in range(3):
                    if j >= 0:
                        q = inv[f, j, c, 0] * x + inv[f, j, c, 1] * y + inv[f, j, c, 2] * z + inv[f, j, c, 3]
                    else:
                        q = x if c == 0 else (y if c == 1 else z)
                    if q < lo[f, i, c]:
                        lo[f, i, c] = q
                    if q > hi[f, i, c]:
                        hi[f, i, c] = q


def node_boxes_numpy(ptr, vert, ref, posed, inv) -> tuple[np.ndarray, np.ndarray]:
    """Reference of the box kernel: (lo, hi) (n, N, 3)."""
    n, N = posed.shape[0], ptr.shape[0] - 1
    lo = np.full((n, N, 3), np.inf)
    hi = np.full((n, N, 3), -np.inf)
    for i in range(N):
        if ref[i] < -1:
            continue
        p = posed[:, vert[ptr[i]:ptr[i + 1]]]
        if ref[i] >= 0:
            m = inv[:, ref[i]]
            p = np.einsum("frc,fvc->fvr", m[:, :, :3], p) + m[:, None, :, 3]
        if p.shape[1]:
            lo[:, i], hi[:, i] = p.min(1), p.max(1)
    return lo, hi


def node_boxes(frames, ptr, vert, ref, chunk: int = FRAME_CHUNK, rows=None) -> np.ndarray:
    """(N, 2, 3) float64 [lo, hi] per node over every frame (of ``rows``: one clip's), in the frame of joint
    ``ref[i]`` (skinned frames) or the model frame (-1); empty nodes get a zero box at the origin."""
    N = ptr.shape[0] - 1
    lo = np.full((N, 3), np.inf)
    hi = np.full((N, 3), -np.inf)
    ref = np.ascontiguousarray(ref, np.int64)
    skinned = hasattr(frames, "joint_inverses")
    for r in row_chunks(frames, rows, chunk):
        posed = frames.positions(r)
        inv = frames.joint_inverses(r)[0] if skinned else np.zeros((r.shape[0], 1, 3, 4))
        todo = [(posed, inv)]
        if skinned and frames.morphs:  # the blend's middle control points, seen from both rows' frames
            pr = r[frames.paired[r]]
            if pr.size:
                mid = frames.control_points(pr)
                todo += [(mid, frames.joint_inverses(pr)[0]), (mid, frames.joint_inverses(pr + 1)[0])]
        for P, I in todo:
            l, h = np.empty((P.shape[0], N, 3)), np.empty((P.shape[0], N, 3))
            _box_kernel(ptr, vert, ref, P, I, l, h)
            lo = np.minimum(lo, l.min(0))
            hi = np.maximum(hi, h.max(0))
    empty = ~(lo <= hi).all(1)
    lo[empty] = 0.0
    hi[empty] = 0.0
    return np.stack([lo, hi], axis=1)


def segment_boxes(frames: KeyframedFrames, ptr, vert) -> np.ndarray:
    """(F, N, 2, 3) float64 node boxes (model frame) at every frame of a keyframed character."""
    N = ptr.shape[0] - 1
    out = np.zeros((frames.n_frames, N, 2, 3))
    ref = np.full(N, -1, np.int64)
    for a, b in chunks(frames.n_frames):
        posed = frames.positions(np.arange(a, b))
        l, h = np.empty((b - a, N, 3)), np.empty((b - a, N, 3))
        _box_kernel(ptr, vert, ref, posed, np.zeros((b - a, 1, 3, 4)), l, h)
        empty = ~(l <= h).all(2)
        l[empty] = 0.0
        h[empty] = 0.0
        out[a:b, :, 0], out[a:b, :, 1] = l, h
    return out


__all__ = ["CHOICE_TRIANGLES", "STRETCH_CAP", "choose_poses", "degenerate_tolerance", "frame_grams", "grams",
           "largest_areas", "node_boxes", "node_boxes_numpy", "node_coverage", "coverage_numpy", "reference_joints",
           "segment_boxes", "stretch_numpy", "subtree_triangles", "subtree_vertices"]
