"""CPU side of the ``"clusters"`` drawer (``render/clusters/draw.py``): per-frame grouping of
instance cuts, gathering of their triangles (numba kernels beside numpy references), the
ranges of multi-draw commands, geomorph rows, and the pieces of a palette chunk.

Claudio, Kim, Kim, Yoon, *VDR-AM*, §5.1 (cuts drawn instanced per distinct cut); the
module split from ``render/clusters/draw.py`` unchanged, which re-exports these names.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from numba import njit


#: float of the instance data holding the instance's palette slot (i_anim.y)
PALETTE_SLOT_FLOAT = 13


# ---------------------------------------------------------------------------- CPU side (numpy + numba)
def group_cuts(offsets: np.ndarray, clusters: np.ndarray):
    """Group instances by identical cut.

    Parameters
    ----------
    offsets : (k+1,) int64 CSR offsets; clusters : (offsets[-1],) int32

    Returns
    -------
    order : (k,) int64 instance order with each group contiguous (groups in
        order of first appearance, instances in original order within a group)
    counts : (G,) int64 instances per group
    first : (G,) int64 an instance (original index) of each group
    """
    k = int(offsets.shape[0]) - 1
    ids: dict = {}
    gid = np.empty(k, np.int64)
    raw = np.ascontiguousarray(clusters, np.int32)
    for i in range(k):
        gid[i] = ids.setdefault(raw[offsets[i]:offsets[i + 1]].tobytes(), len(ids))
    order = np.argsort(gid, kind="stable")
    counts = np.bincount(gid, minlength=len(ids)).astype(np.int64)
    first = np.full(len(ids), -1, np.int64)
    first[gid[::-1]] = np.arange(k - 1, -1, -1)
    return order, counts, first


def gather_numpy(flat_indices, tri_start, cut_offsets, cut_clusters):
    """Reference of :func:`gather`: the concatenated triangles of each cut.

    Parameters
    ----------
    flat_indices : (3M,) uint16/uint32 hierarchy indices, flattened
    tri_start : (N+1,) int64
    cut_offsets : (G+1,) int64; cut_clusters : int32 (CSR cuts)

    Returns
    -------
    out : (3 * triangles,) uint32; first : (G+1,) int64 first index element of each cut
    """
    parts, first = [], [0]
    for g in range(cut_offsets.shape[0] - 1):
        n = 0
        for c in cut_clusters[cut_offsets[g]:cut_offsets[g + 1]]:
            a, b = 3 * int(tri_start[c]), 3 * int(tri_start[c + 1])
            parts.append(np.asarray(flat_indices[a:b], np.uint32))
            n += b - a
        first.append(first[-1] + n)
    out = np.concatenate(parts) if parts else np.zeros(0, np.uint32)
    return out, np.asarray(first, np.int64)


@njit(cache=True)
def _gather_kernel(flat, tri_start, co, cc, first, out):  # pragma: no cover - compiled
    for g in range(co.shape[0] - 1):
        o = first[g]
        for j in range(co[g], co[g + 1]):
            c = cc[j]
            for e in range(3 * tri_start[c], 3 * tri_start[c + 1]):
                out[o] = flat[e]
                o += 1


def gather(flat_indices, tri_start, cut_offsets, cut_clusters):
    """The concatenated triangles of each cut (numba; see :func:`gather_numpy`)."""
    tc = 3 * np.diff(tri_start)
    per = tc[cut_clusters] if cut_clusters.size else np.zeros(0, np.int64)
    cs = np.concatenate([[0], np.cumsum(per)]).astype(np.int64)
    first = cs[cut_offsets]
    out = np.empty(int(first[-1]) if first.size else 0, np.uint32)
    if out.size:
        _gather_kernel(flat_indices, np.asarray(tri_start, np.int64), np.asarray(cut_offsets, np.int64),
                       np.asarray(cut_clusters, np.int32), first, out)
    return out, first


def range_commands_numpy(tri_start, cut_offsets, cut_clusters, counts, base):
    """Reference of :func:`range_commands`: (C, 5) uint32 indirect commands, one
    per run of consecutive clusters (adjacent in the hierarchy's index buffer)
    of each cut; cut g is drawn ``counts[g]`` times from instance ``base[g]``."""
    rows = []
    for g in range(cut_offsets.shape[0] - 1):
        cl = cut_clusters[cut_offsets[g]:cut_offsets[g + 1]]
        j = 0
        while j < cl.shape[0]:
            a = int(tri_start[cl[j]])
            b = int(tri_start[cl[j] + 1])
            while j + 1 < cl.shape[0] and int(tri_start[cl[j + 1]]) == b:
                j += 1
                b = int(tri_start[cl[j] + 1])
            if b > a:
                rows.append((3 * (b - a), int(counts[g]), 3 * a, 0, int(base[g])))
            j += 1
    return np.asarray(rows, np.uint32).reshape(-1, 5)


@njit(cache=True)
def _range_kernel(tri_start, co, cc, counts, base, out):  # pragma: no cover - compiled
    n = 0
    for g in range(co.shape[0] - 1):
        j = co[g]
        while j < co[g + 1]:
            a = tri_start[cc[j]]
            b = tri_start[cc[j] + 1]
            while j + 1 < co[g + 1] and tri_start[cc[j + 1]] == b:
                j += 1
                b = tri_start[cc[j] + 1]
            if b > a:
                out[n, 0] = 3 * (b - a)
                out[n, 1] = counts[g]
                out[n, 2] = 3 * a
                out[n, 3] = 0
                out[n, 4] = base[g]
                n += 1
            j += 1
    return n


def range_commands(tri_start, cut_offsets, cut_clusters, counts, base):
    """(C, 5) uint32 indirect commands per run of consecutive clusters (numba)."""
    out = np.empty((max(int(cut_clusters.shape[0]), 1), 5), np.uint32)
    n = _range_kernel(np.asarray(tri_start, np.int64), np.asarray(cut_offsets, np.int64),
                      np.asarray(cut_clusters, np.int32), np.asarray(counts, np.int64),
                      np.asarray(base, np.int64), out)
    return out[:n].copy()


def split_morph_rows(offsets, clusters, heights, weights):
    """Split the rows of a geomorphed CSR cut by (morph height, weight) of their entries.

    Parameters
    ----------
    offsets : (k+1,) int64; clusters : (E,) int32 the union cuts (``lod.clusters.morph.morph_union``)
    heights : (E,) int32 morph height per entry (< 0: unmoved); weights : (E,) float32 blend weights

    Returns
    -------
    offsets : (m+1,) int64; clusters : (E,) int32 the entries regrouped, one row per distinct
        (instance, height, weight) in instance order
    rows : (m,) int64 the instance each new row belongs to
    heights, weights : (m,) float32 the row's morph height and weight (as the instance data stores them)
    """
    offsets = np.asarray(offsets, np.int64)
    clusters = np.asarray(clusters, np.int32)
    h = np.asarray(heights, np.int64)
    w = np.asarray(weights, np.float32)
    if not (h.shape == w.shape == clusters.shape):
        raise ValueError(f"geomorphed cut: {clusters.shape[0]} clusters, {h.shape[0]} heights, {w.shape[0]} weights")
    w = np.where(h < 0, np.float32(0.0), np.nan_to_num(w, nan=0.0, posinf=1.0, neginf=0.0)).astype(np.float32)
    inst = np.repeat(np.arange(offsets.shape[0] - 1), np.diff(offsets))
    order = np.lexsort((w, h, inst))
    inst, h, w, c = inst[order], h[order], w[order], clusters[order]
    new = np.ones(inst.shape[0], bool)
    new[1:] = (inst[1:] != inst[:-1]) | (h[1:] != h[:-1]) | (w[1:] != w[:-1])
    starts = np.flatnonzero(new)
    out_off = np.append(starts, inst.shape[0]).astype(np.int64)
    return out_off, c, inst[starts].astype(np.int64), h[starts].astype(np.float32), w[starts]


def _cut_arrays(b, n_leaves: int):
    """(offsets, clusters) of a batch: its cut, or every leaf (full detail) for a plain DrawBatch."""
    off = getattr(b, "offsets", None)
    if off is not None and off.shape[0] == b.n_instances + 1:
        return np.asarray(off, np.int64), np.asarray(b.clusters, np.int32)
    k = b.n_instances
    return (np.arange(k + 1, dtype=np.int64) * n_leaves,
            np.tile(np.arange(n_leaves, dtype=np.int32), k))


def _slice_item(it, first: int, n: int):
    """Instances ``first .. first + n`` of a collected item (``Drawer._collect``) as an item of
    their own, palette slots renumbered from 0 (one piece of a palette chunk)."""
    rows = np.arange(first, first + n, dtype=np.int64)
    offsets, clusters = _sub_csr(it.offsets, it.clusters, rows)
    data = it.data[first:first + n].copy()
    data[:, PALETTE_SLOT_FLOAT] = np.arange(n, dtype=np.float32)
    return SimpleNamespace(st=it.st, key=it.key, tint=it.tint, fade=it.fade, k=n, data=data,
                           words=it.words[first:first + n], offsets=offsets, clusters=clusters,
                           ids=it.ids[first:first + n], part=it.part[first:first + n],
                           first_row=it.first_row[first:first + n], program=it.program,
                           slots=None if getattr(it, "slots", None) is None else it.slots[first:first + n])


def _sub_csr(offsets: np.ndarray, clusters: np.ndarray, sub: np.ndarray):
    """CSR (offsets, clusters) of the rows ``sub`` (int array) of a CSR array."""
    sub = np.asarray(sub, np.int64)
    lens = offsets[sub + 1] - offsets[sub]
    out_off = np.zeros(sub.shape[0] + 1, np.int64)
    np.cumsum(lens, out=out_off[1:])
    total = int(out_off[-1])
    if total == 0:
        return out_off, np.zeros(0, np.int32)
    idx = np.repeat(offsets[sub] - out_off[:-1], lens) + np.arange(total)
    return out_off, clusters[idx]
