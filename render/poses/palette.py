"""The per-frame skinning palette: a transform-feedback pre-pass that blends each
drawn instance's joint matrices once per frame, in chunks that fit the texture.

The pre-pass (``shaders/poses/palette.vert``, one point per matrix row and instance)
blends every instance's joint matrices between the two baked frames around its
fractional frame coordinate (exact for linear blend skinning, see
``lod.full.reps.SkinnedRep``); the result is copied GPU-side into an RGBA32F
palette texture of :data:`PALETTE_WIDTH` texels per row, from which the skinned
vertex shaders read three texels per influence (``shaders/poses/skinning.glsl``).

Chunks: one frame's palette holds at most :data:`PALETTE_MAX_TEXELS` texels (the
shaders locate an instance's block with a float division corrected by one row,
exact up to 2**25) and at most ``GL_MAX_TEXTURE_SIZE`` rows. A frame that needs
more (a million skinned instances x 21 joints x 3 texels = 63 M) is drawn in
chunks: :func:`plan_chunks` cuts the frame's skinned draws, in draw order, into
pieces of whole instances whose palette fits the chunk limit (a draw larger
than the limit is split by instances), and the drawer builds the palette of one
chunk, draws it, then builds the next. The chunk limit
(:attr:`Palette.max_texels`, default :data:`PALETTE_CHUNK_TEXELS`) is kept well
below the shader limit so that the palette's buffer and texture stay small
(64 MB each): GL orders the rewrite of the palette after the draws that read it,
so chunks cost one more pre-pass each and never a wrong pixel (tested: a small
injected limit draws the same pixels as one unchunked palette).
"""
from __future__ import annotations

import moderngl
import numpy as np

#: texels per row of the per-frame skinning palette (a multiple of 3, so the
#: three rows of one matrix never straddle two texture rows)
PALETTE_WIDTH = 4095
#: most palette texels one chunk may address: the shader locates an instance's block with a
#: float division corrected by one row, exact up to 2**25
PALETTE_MAX_TEXELS = 1 << 25
#: default chunk size (texels): 4 M texels = 64 MB of buffer and 64 MB of texture
PALETTE_CHUNK_TEXELS = 1 << 22


def joint_texture(ctx, key: str, joint_table):
    """The baked joint table of representation ``key`` (F frames x J joints x 3 rows of 4) as the RGBA32F texture
    the palette pre-pass and the skinning shaders read (``3 J`` texels wide, ``F`` rows, nearest, no repeat);
    ValueError naming the representation when it passes the GL texture limit."""
    jt = np.ascontiguousarray(joint_table, np.float32)
    F, J = jt.shape[0], jt.shape[1]
    maxs = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
    if 3 * J > maxs or F > maxs:
        raise ValueError(f"representation {key!r}: joint table of {F} frames x {J} joints exceeds the GL texture "
                         f"limit {maxs} (at most {maxs} baked frames and {maxs // 3} joints)")
    tex = ctx.texture((3 * J, F), 4, jt.tobytes(), dtype="f4")
    tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    tex.repeat_x = tex.repeat_y = False
    return tex


def plan_chunks(sizes, per_instance, max_texels: int) -> list:
    """Cut skinned draws into palette chunks.

    Parameters
    ----------
    sizes : instances of each draw, in draw order
    per_instance : palette texels of one instance of each draw (3 x joints)
    max_texels : most texels of one chunk (> 0)

    Returns
    -------
    list of chunks, each a list of ``(draw, first instance, count)`` in draw
    order; consecutive pieces of one draw keep its instance order. A draw with
    no instances appears in no chunk. Raises ValueError when one instance
    alone exceeds ``max_texels``.
    """
    max_texels = int(max_texels)
    chunks, cur, used = [], [], 0
    for d, (k, t) in enumerate(zip(sizes, per_instance)):
        k, t = int(k), int(t)
        if k <= 0:
            continue
        if t > max_texels:
            raise ValueError(f"skinning palette: one instance needs {t} texels, above the chunk limit {max_texels}")
        first = 0
        while first < k:
            room = (max_texels - used) // t
            if room == 0:
                chunks.append(cur)
                cur, used = [], 0
                continue
            n = min(room, k - first)
            cur.append((d, first, n))
            used += n * t
            first += n
    if cur:
        chunks.append(cur)
    return chunks


class Palette:
    """The palette buffer and texture of a renderer (created on first use, grown by doubling).

    Parameters
    ----------
    ctx : moderngl context; track : ``track(obj, label)`` registering a GL object
        with its owner (released in reverse creation order); untrack : ``untrack(obj)``
    """

    def __init__(self, ctx, track, untrack):
        self.ctx = ctx
        self._track = track
        self._untrack = untrack
        #: texels per row (a multiple of 3)
        self.width = PALETTE_WIDTH
        #: most texels of one chunk (<= PALETTE_MAX_TEXELS)
        self.max_texels = PALETTE_CHUNK_TEXELS
        self.buffer = None
        self.texture = None
        self.rows = 0
        #: palette passes of the last frame (chunks)
        self.passes = 0

    @property
    def chunk_texels(self) -> int:
        return int(min(PALETTE_MAX_TEXELS, max(1, self.max_texels)))

    def ensure(self, rows: int) -> None:
        """Buffer and texture large enough for ``rows`` texel rows."""
        if self.texture is not None and self.texture.width != self.width:
            self.rows = 0  # width changed: rebuild
        if rows <= self.rows:
            return
        limit = int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])
        if self.width % 3 or not 3 <= self.width <= limit:
            raise ValueError(f"Renderer.palette_width: expected a multiple of 3 within the GL texture limit, "
                             f"got {self.width}")
        if rows > limit:
            raise ValueError(f"Renderer: the skinning palette needs {rows} texture rows, above the GL limit {limit}; "
                             "lower the palette chunk size (Renderer.palette_chunk_texels)")
        cap = max(1, self.rows)
        while cap < rows:
            cap *= 2
        cap = min(cap, limit)
        for o in (self.texture, self.buffer):
            if o is not None:
                o.release()
                self._untrack(o)
        self.buffer = self._track(self.ctx.buffer(reserve=cap * self.width * 16, dynamic=True),
                                  "render.palette_buffer")
        self.texture = self._track(self.ctx.texture((self.width, cap), 4, dtype="f4"), "render.poses.palette")
        self.texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.rows = cap

    def upload(self, texels) -> None:
        """Write ``texels`` ((n, 4) float32, palette blocks one after another, e.g. the pose cache's
        palettes blended on the CPU) from texel 0; at most :data:`PALETTE_MAX_TEXELS`."""
        import numpy as np

        t = np.ascontiguousarray(texels, np.float32).reshape(-1, 4)
        if t.shape[0] > PALETTE_MAX_TEXELS:
            raise ValueError(f"skinning palette: {t.shape[0]} texels exceed {PALETTE_MAX_TEXELS}")
        rows = max(1, -(-t.shape[0] // self.width))
        self.ensure(rows)
        full = np.zeros((rows * self.width, 4), np.float32)
        full[:t.shape[0]] = t
        self.texture.write(full.tobytes(), viewport=(0, 0, self.width, rows))

    def build(self, program, items, instance_bytes: int) -> list:
        """Run the pre-pass for ``items`` (one chunk: their texels must fit :attr:`chunk_texels`).

        program : the ``palette`` transform-feedback program (varying ``v_row``)
        items : list of (_GpuRep with ``joints``, ``palette_vao``, ``n_joints``; instance buffer;
            byte offset of the first instance; instance count)
        Returns each item's first palette texel; leaves the texture bound to unit 1.
        """
        total = sum(k * 3 * g.n_joints for g, _, _, k in items)
        if total > PALETTE_MAX_TEXELS:
            raise ValueError(f"Renderer: {total} skinning-palette texels in one chunk exceed {PALETTE_MAX_TEXELS} "
                             "(instances x 3 x joints); cut the draws with render.poses.palette.plan_chunks")
        rows = max(1, -(-total // self.width))
        self.ensure(rows)
        program["u_joints"].value = 0
        loc = program["i_anim"].location
        bases, base = [], 0
        for g, buf, offset, k in items:
            g.joints.use(0)
            g.palette_vao.bind(loc, "f", buf, "4f", offset=offset + 48, stride=instance_bytes, divisor=1)
            g.palette_vao.transform(self.buffer, self.ctx.POINTS, vertices=3 * g.n_joints, instances=k,
                                    buffer_offset=base * 16)
            bases.append(base)
            base += k * 3 * g.n_joints
        self.texture.write(self.buffer, viewport=(0, 0, self.texture.width, rows))
        self.texture.use(1)
        self.passes += 1
        return bases


class PaletteCursor:
    """Which palette chunk (:func:`plan_chunks`) the texture holds while a frame's pieces are drawn.

    ``base(c, j)`` builds chunk ``c`` with ``build`` (``Renderer._build_palette``) when it is not the one
    in the texture, then rebinds the framebuffer that was bound (the camera's or the shadow map's), and
    returns item ``j``'s first texel. Pieces come in draw order, so each chunk is built once per pass;
    :meth:`invalidate` after anything else wrote the palette (the cluster drawer's own pre-pass)."""

    def __init__(self, build, chunks: list, ctx):
        self._build, self.chunks, self.ctx = build, chunks, ctx
        self.built, self.bases = -1, []

    def base(self, c: int, j: int) -> int:
        if c != self.built:
            fbo = self.ctx.fbo
            self.bases, self.built = self._build([p[:4] for p in self.chunks[c]]), c
            fbo.use()
        return self.bases[j]

    def invalidate(self) -> None:
        self.built = -1
