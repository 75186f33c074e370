"""Per-instance colour variation and debug colours, one path for every draw.

Every drawn instance carries two uint32 words, ``(variation, debug)``
(``shaders/core/tint.glsl`` decodes them in every vertex shader and in the point
splat's colour pass, so full detail, LOD chains, clusters and points give an
instance the same colour and a LOD switch never changes one):

- variation: bytes ``(b0, b1, b2, mode)``; mode :data:`MODE_HSV` shifts the hue
  by ``(b0 - 128) / 256`` turns and scales saturation and value by ``b1 / 128``
  and ``b2 / 128``; mode :data:`MODE_PALETTE` replaces the colour by
  ``(b0, b1, b2) / 255``; mode 0 leaves it. Weighted by the vertex colour's
  alpha, the character's variation mask (its regions: 1 varies, 0 is kept).
- debug: RGBA8 ``(r, g, b, weight)`` mixed in afterwards (``DrawBatch.tint``,
  the fly-through's colour-by; ``lod.debug_colors``).

Why a table of packed words per agent rather than a hash in the shader: the
variation of an agent depends on its character's settings (amounts, palette,
on or off), which a shader would need as per-representation uniforms, while
the point drawer splats the instances of all representations in one dispatch;
a word per instance carries any setting through every path alike. The words
come from a per-agent table made once (:func:`variation_table`, 4 bytes per
agent, deterministic from the scene seed and the agent index, never from draw
order or LOD) and are gathered per frame by the batches' agent ids (8 bytes
per instance uploaded beside the 64 of the instance data).

Colour conversion: HSV after Sam Hocevar's branchless form (also in
``tint.glsl``); :func:`apply_tint` is the numpy reference of the shader.
"""
from __future__ import annotations

import numpy as np

#: uint32 words per instance: (variation, debug)
TINT_WORDS = 2
#: bytes per instance in the tint stream
TINT_BYTES = 4 * TINT_WORDS
#: variation modes (the word's top byte)
MODE_NONE, MODE_HSV, MODE_PALETTE = 0, 1, 2
#: largest hue shift a word holds, turns (b0 = 0 is -0.5)
MAX_HUE = 0.5
#: largest saturation / value factor a word holds (b = 255)
MAX_FACTOR = 255.0 / 128.0


def _u32(x) -> np.ndarray:
    return np.asarray(x, np.uint64) & np.uint64(0xFFFFFFFF)


def hash_uniform(seed: int, ids, salt: int) -> np.ndarray:
    """(n,) float64 in [0, 1): a counter-based hash (splitmix64 finaliser) of
    (seed, id, salt): the same inputs give the same numbers on any machine and
    in any order; another seed or salt gives independent ones."""
    ids = np.asarray(ids, np.int64).astype(np.uint64)
    with np.errstate(over="ignore"):
        key = (int(seed) * 0x632BE59BD9B4E019 + int(salt) * 0x85EBCA77C2B2AE63) & 0xFFFFFFFFFFFFFFFF
        z = ids * np.uint64(0x9E3779B97F4A7C15) + np.uint64(key)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(np.float64) / float(1 << 53)


def _byte(x) -> np.ndarray:
    return np.clip(np.rint(np.nan_to_num(np.asarray(x, np.float64), nan=0.0)), 0, 255).astype(np.uint32)


def pack_hsv(hue, saturation, value) -> np.ndarray:
    """(n,) uint32 HSV-shift words: ``hue`` shift in turns (clamped to
    [-0.5, 0.496]), ``saturation`` and ``value`` factors (clamped to [0, 1.99])."""
    h = _byte(np.asarray(hue, np.float64) * 256.0 + 128.0)
    s = _byte(np.asarray(saturation, np.float64) * 128.0)
    v = _byte(np.asarray(value, np.float64) * 128.0)
    return h | (s << 8) | (v << 16) | np.uint32(MODE_HSV << 24)


def pack_rgba8(rgb, weight=1.0, mode=None) -> np.ndarray:
    """(n,) uint32 words of colours (n, 3) in [0, 1] and a weight (or a mode) in the top byte."""
    c = _byte(np.clip(np.asarray(rgb, np.float64).reshape(-1, 3), 0.0, 1.0) * 255.0)
    top = np.uint32(mode) if mode is not None else _byte(np.clip(np.asarray(weight, np.float64), 0.0, 1.0) * 255.0)
    return (c[:, 0] | (c[:, 1] << 8) | (c[:, 2] << 16) | (top << 24)).astype(np.uint32)


def debug_word(tint) -> int:
    """The debug word of ``DrawBatch.tint`` ((r, g, b, weight) or None: 0, true colours)."""
    if tint is None:
        return 0
    t = np.nan_to_num(np.asarray(tint, np.float64).reshape(4), nan=0.0)
    return int(pack_rgba8(t[:3], t[3])[0])


def variation_words(seed: int, ids, hue: float = 0.0, saturation: float = 0.0, value: float = 0.0,
                    palette=None, salt: int = 0) -> np.ndarray:
    """(n,) uint32 variation words of agents ``ids`` of one character.

    hue : largest hue shift, turns (each agent: uniform in [-hue, hue]);
    saturation, value : largest relative change (factor uniform in [1 - x, 1 + x]);
    palette : (m, 3) colours in [0, 1]: each agent takes one (uniformly), instead of the shifts.
    salt : separates characters that share agent ids (0 is fine: ids are unique).
    """
    ids = np.asarray(ids, np.int64)
    if palette is not None and len(palette):
        pal = np.asarray(palette, np.float64).reshape(-1, 3)
        k = np.minimum((hash_uniform(seed, ids, salt * 4 + 3) * pal.shape[0]).astype(np.int64), pal.shape[0] - 1)
        return pack_rgba8(pal[k], mode=MODE_PALETTE)
    u = [2.0 * hash_uniform(seed, ids, salt * 4 + k) - 1.0 for k in range(3)]
    return pack_hsv(hue * u[0], 1.0 + saturation * u[1], 1.0 + value * u[2])


def variation_table(seed: int, character, settings, ids=None) -> np.ndarray:
    """(n,) uint32 variation word of every agent: ``character`` (n,) the agents'
    character indices, ``settings[c]`` a dict (``hue``, ``saturation``,
    ``value``, ``palette``) or None (no variation) per character; ``ids`` (n,)
    the agents' stable ids (default their indices: a crowd whose count never
    changed), so an agent keeps its colour while others leave and enter."""
    character = np.asarray(character, np.int64)
    ids = np.arange(character.shape[0]) if ids is None else np.asarray(ids, np.int64)
    out = np.zeros(character.shape[0], np.uint32)
    for c, s in enumerate(settings):
        if not s:
            continue
        rows = np.flatnonzero(character == c)
        out[rows] = variation_words(seed, ids[rows], hue=float(s.get("hue", 0.0)),
                                    saturation=float(s.get("saturation", 0.0)), value=float(s.get("value", 0.0)),
                                    palette=s.get("palette"))
    return out


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


def batch_words(batches, table) -> np.ndarray:
    """(sum k, 2) uint32 words of ``batches`` in order (the order of their instance data); batches of
    the :data:`UNVARIED` families get no variation (their debug colour still applies)."""
    parts = [instance_words(None if b.rep.split(":", 1)[0] in UNVARIED else table, b.instance_ids,
                            getattr(b, "tint", None)) for b in batches]
    return np.concatenate(parts) if parts else np.zeros((0, TINT_WORDS), np.uint32)


# ---------------------------------------------------------------------------------------------- numpy reference
def rgb_to_hsv(c: np.ndarray) -> np.ndarray:
    """(n, 3) HSV of (n, 3) RGB, as ``tint_rgb_to_hsv`` in tint.glsl."""
    c = np.asarray(c, np.float64).reshape(-1, 3)
    r, g, b = c[:, 0], c[:, 1], c[:, 2]
    sel = (g >= b)[:, None]
    p = np.where(sel, np.stack([g, b, np.zeros_like(r), np.full_like(r, -1.0 / 3.0)], 1),
                 np.stack([b, g, np.full_like(r, -1.0), np.full_like(r, 2.0 / 3.0)], 1))
    sel = (r >= p[:, 0])[:, None]
    q = np.where(sel, np.stack([r, p[:, 1], p[:, 2], p[:, 0]], 1), np.stack([p[:, 0], p[:, 1], p[:, 3], r], 1))
    d = q[:, 0] - np.minimum(q[:, 3], q[:, 1])
    e = 1e-10
    return np.stack([np.abs(q[:, 2] + (q[:, 3] - q[:, 1]) / (6.0 * d + e)), d / (q[:, 0] + e), q[:, 0]], 1)


def hsv_to_rgb(c: np.ndarray) -> np.ndarray:
    """(n, 3) RGB of (n, 3) HSV, as ``tint_hsv_to_rgb`` in tint.glsl."""
    c = np.asarray(c, np.float64).reshape(-1, 3)
    p = np.abs(np.mod(c[:, :1] + np.array([1.0, 2.0 / 3.0, 1.0 / 3.0]), 1.0) * 6.0 - 3.0)
    return c[:, 2:3] * (1.0 + (np.clip(p - 1.0, 0.0, 1.0) - 1.0) * c[:, 1:2])


def apply_tint(color, words) -> np.ndarray:
    """(n, 3) float64 RGB of vertex colours (n, 4) (alpha = variation mask)
    under words (n, 2) (or (2,)): the numpy reference of ``tint_color``."""
    col = np.asarray(color, np.float64).reshape(-1, 4)
    w = np.broadcast_to(np.asarray(words, np.uint32).reshape(-1, TINT_WORDS), (col.shape[0], TINT_WORDS))
    rgb = np.clip(col[:, :3], 0.0, 1.0)
    mask = np.clip(col[:, 3:4], 0.0, 1.0)
    b = np.stack([(w[:, 0] >> (8 * k)) & 255 for k in range(4)], 1).astype(np.float64)
    hsv = rgb_to_hsv(rgb)
    hsv[:, 0] = np.mod(hsv[:, 0] + (b[:, 0] - 128.0) / 256.0, 1.0)
    hsv[:, 1] = np.clip(hsv[:, 1] * b[:, 1] / 128.0, 0.0, 1.0)
    hsv[:, 2] = np.clip(hsv[:, 2] * b[:, 2] / 128.0, 0.0, 1.0)
    shifted = rgb + (hsv_to_rgb(hsv) - rgb) * mask
    pal = rgb + (b[:, :3] / 255.0 - rgb) * mask
    out = np.where((b[:, 3] == MODE_HSV)[:, None], shifted, np.where((b[:, 3] == MODE_PALETTE)[:, None], pal, rgb))
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
