"""Per-instance colour words on the GPU, one path for every draw.

Every drawn instance carries two uint32 words, ``(variation, debug)``
(``shaders/core/tint.glsl`` decodes them in every vertex shader and in the point
splat's colour pass, so full detail, LOD chains, clusters and points give an
instance the same colour and a LOD switch never changes one):

- variation: the agent's colour-variation word (``lod.variation``: its bytes,
  its table by stable id, its arithmetic in numpy), weighted by the vertex
  colour's alpha, the character's variation mask (its regions: 1 varies, 0 is kept).
- debug: RGBA8 ``(r, g, b, weight)`` mixed in afterwards (``DrawBatch.tint``,
  the fly-through's colour-by; ``lod.debug_colors``).

Why a table of packed words per agent rather than a hash in the shader: the
variation of an agent depends on its character's settings (amounts, palette,
on or off), which a shader would need as per-representation uniforms, while
the point drawer splats the instances of all representations in one dispatch;
a word per instance carries any setting through every path alike. The words
come from a per-agent table made once (``lod.variation.variation_table``, 4 bytes
per agent) and are gathered per frame by the batches' agent ids (8 bytes per
instance uploaded beside the 64 of the instance data). Representations whose
colours already carry their agents' variation (the super-hierarchy nodes of
``lod.points.instancing``, which stand for many agents) and scenery get none
(:data:`PREVARIED`, :data:`UNVARIED`).

:func:`apply_tint` is the numpy reference of the shader.
"""
from __future__ import annotations

import numpy as np

from lod.variation import pack_rgba8, vary

#: uint32 words per instance: (variation, debug)
TINT_WORDS = 2
#: bytes per instance in the tint stream
TINT_BYTES = 4 * TINT_WORDS


def debug_word(tint) -> int:
    """The debug word of ``DrawBatch.tint`` ((r, g, b, weight) or None: 0, true colours)."""
    if tint is None:
        return 0
    t = np.nan_to_num(np.asarray(tint, np.float64).reshape(4), nan=0.0)
    return int(pack_rgba8(t[:3], t[3])[0])


def instance_words(table, ids, tint=None) -> np.ndarray:
    """(k, 2) uint32 words of one batch: the agents' variation words (0 where
    ``table`` is None or an id is negative -- scenery -- or outside it) and the
    batch's debug word."""
    ids = np.asarray(ids, np.int64).reshape(-1)
    out = np.zeros((ids.shape[0], TINT_WORDS), np.uint32)
    if table is not None and ids.shape[0]:
        t = np.asarray(table, np.uint32)
        ok = (ids >= 0) & (ids < t.shape[0])
        out[ok, 0] = t[ids[ok]]
    out[:, 1] = debug_word(tint)
    return out


#: representation families never varied (scenery: terrain, props); their instance ids are not agents
UNVARIED = ("static",)
#: representation keys whose colours already carry their agents' variation (a super-hierarchy node stands for
#: many agents: lod.points.instancing bakes each one's word into its source points)
PREVARIED = ("points:super:",)


def takes_variation(key: str) -> bool:
    """True when the instances of representation ``key`` get their agent's variation word."""
    return key.split(":", 1)[0] not in UNVARIED and not key.startswith(PREVARIED)


def batch_words(batches, table) -> np.ndarray:
    """(sum k, 2) uint32 words of ``batches`` in order (the order of their instance data); batches of
    the :data:`UNVARIED` families and of :data:`PREVARIED` keys get no variation (their debug colour
    still applies)."""
    parts = [instance_words(table if takes_variation(b.rep) else None, b.instance_ids,
                            getattr(b, "tint", None)) for b in batches]
    return np.concatenate(parts) if parts else np.zeros((0, TINT_WORDS), np.uint32)


def apply_tint(color, words) -> np.ndarray:
    """(n, 3) float64 RGB of vertex colours (n, 4) (alpha = variation mask)
    under words (n, 2) (or (2,)): the numpy reference of ``tint_color``."""
    col = np.asarray(color, np.float64).reshape(-1, 4)
    w = np.broadcast_to(np.asarray(words, np.uint32).reshape(-1, TINT_WORDS), (col.shape[0], TINT_WORDS))
    out = vary(col, w[:, 0])
    d = np.stack([(w[:, 1] >> (8 * k)) & 255 for k in range(4)], 1).astype(np.float64) / 255.0
    return out + (d[:, :3] - out) * d[:, 3:4]


class TintStream:
    """The per-frame GPU buffer of instance words beside an instance buffer (row
    i of one belongs to row i of the other), bound as the instanced attribute
    ``i_tint`` (uvec2, divisor 1). Owns its buffer; ``release`` is safe twice."""

    def __init__(self, ctx, label: str = "crowd.instance_tints", rows: int = 1024):
        self.ctx, self.label = ctx, label
        self.buffer = None
        self.rows = 0
        self._grow(rows)

    def _grow(self, rows: int) -> None:
        if rows <= self.rows:
            return
        cap = max(1024, self.rows)
        while cap < rows:
            cap *= 2
        if self.buffer is not None:
            self.buffer.release()
        self.buffer = self.ctx.buffer(reserve=cap * TINT_BYTES, dynamic=True)
        self.buffer.label = self.label
        self.rows = cap

    def write(self, words: np.ndarray) -> None:
        """Upload (k, 2) uint32 words for this frame's rows 0..k-1 (the old contents are orphaned)."""
        w = np.ascontiguousarray(words, np.uint32).reshape(-1, TINT_WORDS)
        self._grow(w.shape[0])
        self.buffer.orphan(self.rows * TINT_BYTES)
        if w.shape[0]:
            self.buffer.write(w)

    def bind(self, vao, location, row: int) -> None:
        """Bind ``i_tint`` (at ``location``; None: the program has none) of ``vao`` from row ``row`` on."""
        if location is not None:
            vao.bind(location, "i", self.buffer, "2u", offset=int(row) * TINT_BYTES, stride=TINT_BYTES, divisor=1)

    def release(self) -> None:
        if self.buffer is not None:
            self.buffer.release()
            self.buffer = None
