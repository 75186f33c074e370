"""CPU side of the compute rasteriser's tables (``shaders/raster/raster_common.glsl``): vertex records, triangle rows,
instance records, the 4096-wide textures that hold them, and the slots of the gathered posed vertices
(:func:`pose_slots`).

Why textures: llvmpipe scalarises a storage-buffer load whose address differs per lane (a bounds-checked
load per lane), while ``texelFetch`` runs through its vectorised texture path. Measured on 100 copies of a
60 K-triangle character (6 M triangles, 1280x720, loaded 2-core machine): the triangle pass reading its
corner indices and window positions from storage buffers took 740 ms of CPU, from textures 102 ms; a vertex
pass reading the posed vertices in order, 122 ms against 65 ms.
"""
from __future__ import annotations

import numpy as np

#: triangles per job (raster_common.glsl RS_LOG_CHUNK): a triangle's id is job * CHUNK + index, so a window
#: holds at most 2^32 / CHUNK jobs
LOG_CHUNK = 10
CHUNK = 1 << LOG_CHUNK
#: vertices per thread of the vertex and pose passes (8 threads a work group)
VERTS_PER_THREAD = 16
VERTEX_JOB = 8 * VERTS_PER_THREAD
#: texels per texture row (raster_common.glsl rs_texel: texel t at (t & 4095, t >> 12))
WIDTH = 4096
#: texels per vertex record, per posed vertex, per instance record (raster_common.glsl RS_RECORD, RS_POSED, RS_INST)
RECORD_TEXELS = 3
POSED_TEXELS = 2
INST_TEXELS = 5
#: instance kinds and flags (raster_common.glsl)
STATIC, KEYFRAMED, POSED = 0, 1, 2
CULL, WORLD = 1, 2


def _bits(a) -> np.ndarray:
    """float32 values as their uint32 bit patterns (non-finite values replaced by 0: nothing non-finite
    reaches the GPU)."""
    f = np.nan_to_num(np.asarray(a, np.float32), nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32)
    return np.ascontiguousarray(f).view(np.uint32)


def vertex_records(positions, normals, colors) -> np.ndarray:
    """(V, 12) uint32: RECORD_TEXELS RGBA32UI texels per vertex, floats as bits: (p.xyz, n.x), (n.y, n.z,
    c.r, c.g), (c.b, c.a, 0, 0) -- the float32 values the hardware path's vertex buffers hold."""
    p = _bits(np.asarray(positions, np.float32).reshape(-1, 3))
    n = _bits(np.asarray(normals, np.float32).reshape(-1, 3))
    c = _bits(np.asarray(colors, np.float32).reshape(-1, 4))
    out = np.zeros((p.shape[0], 4 * RECORD_TEXELS), np.uint32)
    out[:, 0:3] = p
    out[:, 3:6] = n
    out[:, 6:10] = c
    return out


def triangle_rows(indices) -> np.ndarray:
    """(T, 4) uint32 rows (a, b, c, 0) of triangle corner indices."""
    t = np.asarray(indices, np.uint32).reshape(-1, 3)
    out = np.zeros((t.shape[0], 4), np.uint32)
    out[:, :3] = t
    return out


def instance_records(rows, u, kind, flags, mesh, posed, screen, tints, verts) -> np.ndarray:
    """(k, 4 * INST_TEXELS) uint32 instance records (raster_common.glsl RsInstance): model rows 0..2 (the
    12 leading floats of lod.drawlist instance data), (u, kind | flags << 8, first mesh record, first posed
    vertex), (first screen vertex, variation word, debug word, vertices)."""
    rows = np.asarray(rows, np.float32).reshape(-1, 16)
    k = rows.shape[0]
    out = np.zeros((k, 4 * INST_TEXELS), np.uint32)
    out[:, :12] = _bits(rows[:, :12])
    out[:, 12] = _bits(np.broadcast_to(np.asarray(u, np.float32), (k,)))
    out[:, 13] = (np.asarray(kind, np.uint32) & 255) | (np.asarray(flags, np.uint32) << 8)
    out[:, 14] = mesh
    out[:, 15] = posed
    out[:, 16] = screen
    out[:, 17:19] = np.asarray(tints, np.uint32).reshape(-1, 2)
    out[:, 19] = verts
    return out


def rows_for(texels: int) -> int:
    """Texture rows (a power of two, at least 1) holding ``texels`` texels."""
    need = max(1, -(-int(texels) // WIDTH))
    return 1 << int(np.ceil(np.log2(need)))


class Table:
    """A 4096-wide texture (``components`` x ``dtype``) grown by doubling its rows; the CPU keeps nothing."""

    def __init__(self, ctx, dtype: str, label: str, track, forget):
        self.ctx, self.dtype, self.label, self._track, self._forget = ctx, dtype, label, track, forget
        self.texture = None
        self.rows = 0

    def ensure(self, texels: int):
        """The texture, reallocated (content lost) when it holds fewer than ``texels`` texels."""
        rows = rows_for(texels)
        if self.texture is None or rows > self.rows:
            import moderngl

            limit = int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])
            if rows > limit:
                raise ValueError(f"compute raster table {self.label}: {texels} texels exceed the "
                                 f"{WIDTH} x {limit} texture limit")
            if self.texture is not None:
                self._forget(self.texture)
            self.texture = self._track(self.ctx.texture((WIDTH, rows), 4, dtype=self.dtype), self.label)
            self.texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self.texture.repeat_x = self.texture.repeat_y = False
            self.rows = rows
        return self.texture

    def write(self, data: np.ndarray, first_texel: int = 0) -> None:
        """Write ``data`` ((n, 4 * m) 32-bit words: n * m texels) from texel ``first_texel`` (the texture must
        hold them: :meth:`ensure`); whole rows are written, so ``first_texel`` must start a row or the data must
        stay within one row."""
        flat = np.ascontiguousarray(data).reshape(-1, 4)
        n = flat.shape[0]
        if not n:
            return
        t0 = int(first_texel)
        row0, col0 = divmod(t0, WIDTH)
        if col0 + n <= WIDTH:
            self.texture.write(flat.tobytes(), viewport=(col0, row0, n, 1))
            return
        if col0:
            raise ValueError("Table.write: data crossing rows must start a row")
        full = n // WIDTH
        if full:
            self.texture.write(flat[:full * WIDTH].tobytes(), viewport=(0, row0, WIDTH, full))
        rest = n - full * WIDTH
        if rest:
            self.texture.write(flat[full * WIDTH:].tobytes(), viewport=(0, row0 + full, rest, 1))


def pose_slots(posed, mesh, slot, vfirst, vcount, share: bool = True) -> tuple:
    """Pose slots of a window's instances: (first posed vertex of each instance (its slot's base: the slot
    holds the instance's vertex range), posed vertices per slot (k,) with 0 for all but the first instance of a
    slot, the instances that represent the slots). Instances of one mesh in the same pose-cache slot with the
    same vertex range share a slot (``share`` False: every instance its own slot); ``posed`` (k,) bool marks the
    skinned instances."""
    k = posed.shape[0]
    base = np.zeros(k, np.int64)
    n = np.zeros(k, np.int64)
    sel = np.flatnonzero(posed)
    if not sel.shape[0]:
        return base, n, sel
    key = np.stack([np.asarray(mesh, np.int64)[sel], np.asarray(slot, np.int64)[sel],
                    np.asarray(vfirst, np.int64)[sel], np.asarray(vcount, np.int64)[sel]]
                   + ([] if share else [sel]), 1)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inv = inv.reshape(-1)
    reps = sel[np.sort(first)]
    order = np.argsort(np.argsort(first))  # unique rows in order of first appearance
    sizes = np.asarray(vcount, np.int64)[reps]
    starts = np.zeros(reps.shape[0], np.int64)
    np.cumsum(sizes[:-1], out=starts[1:])
    base[sel] = starts[order[inv]]
    n[reps] = sizes
    return base, n, reps


def instance_cuts(tcount, vcount, posed_texels, max_tris: int, max_texels: int) -> list:
    """Instance indices where the windows start (and the end): each window's triangles, screen texels, posed
    texels and instance records stay within the limits (an instance above them alone is a window of its own,
    checked by the tables)."""
    cuts, a = [0], 0
    k = tcount.shape[0]
    t = v = p = 0
    for i in range(k):
        nt, nv, npz = int(tcount[i]), int(vcount[i]), int(posed_texels[i])
        if i > a and (t + nt > max_tris or v + nv > max_texels or p + npz > max_texels
                      or (i - a + 1) * INST_TEXELS > max_texels or (t + nt) // CHUNK + (i - a + 1) >= (1 << 32) // CHUNK):
            cuts.append(i)
            a, t, v, p = i, 0, 0, 0
        t, v, p = t + nt, v + nv, p + npz
    cuts.append(k)
    return cuts


def vertex_jobs(vcount, vfirst) -> np.ndarray:
    """(J, 4) uint32 vertex jobs (instance, first vertex, vertices, 0): each instance's vertices in runs of
    VERTEX_JOB."""
    nj = -(-np.asarray(vcount, np.int64) // VERTEX_JOB)
    ji = np.repeat(np.arange(nj.shape[0]), nj)
    js = np.zeros(nj.shape[0], np.int64)
    np.cumsum(nj[:-1], out=js[1:])
    c = np.arange(ji.shape[0]) - js[ji]
    out = np.zeros((ji.shape[0], 4), np.uint32)
    out[:, 0] = ji
    out[:, 1] = vfirst[ji] + c * VERTEX_JOB
    out[:, 2] = np.minimum(VERTEX_JOB, vcount[ji] - c * VERTEX_JOB)
    return out
