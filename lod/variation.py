"""Per-agent colour variation: the words that say how each agent's colours differ, and their arithmetic.

An agent's variation is one uint32 word, deterministic from the scene seed and the agent's stable id (never from
draw order or LOD): bytes ``(b0, b1, b2, mode)``; mode :data:`MODE_HSV` shifts the hue by ``(b0 - 128) / 256``
turns and scales saturation and value by ``b1 / 128`` and ``b2 / 128``; mode :data:`MODE_PALETTE` replaces the
colour by ``(b0, b1, b2) / 255``; mode 0 leaves it. A vertex colour's alpha is the character's variation mask
(1 varies, 0 is kept).

The renderer applies the words per instance in every shader (``render.tint``, ``shaders/core/tint.glsl``);
:func:`vary` is the same arithmetic in numpy: the shader's reference in tests, and the filter of
representations that stand for many agents at once (a super-hierarchy node of ``lod.points.instancing``
carries the colours of every agent it stands for, Wand & Straßer 2002 §3.5-§3.6). Colour conversion: HSV
after Sam Hocevar's branchless form.
"""
from __future__ import annotations

import numpy as np

#: variation modes (the word's top byte)
MODE_NONE, MODE_HSV, MODE_PALETTE = 0, 1, 2
#: largest hue shift a word holds, turns (b0 = 0 is -0.5)
MAX_HUE = 0.5
#: largest saturation / value factor a word holds (b = 255)
MAX_FACTOR = 255.0 / 128.0


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


def vary(color, words) -> np.ndarray:
    """(n, 3) float64 RGB of colours (n, 4) (alpha = variation mask) under variation words (n,) (or one):
    the variation part of ``tint_color`` in ``shaders/core/tint.glsl``."""
    col = np.asarray(color, np.float64).reshape(-1, 4)
    w = np.broadcast_to(np.asarray(words, np.uint32).reshape(-1), (col.shape[0],))
    rgb = np.clip(col[:, :3], 0.0, 1.0)
    mask = np.clip(col[:, 3:4], 0.0, 1.0)
    b = np.stack([(w >> (8 * k)) & 255 for k in range(4)], 1).astype(np.float64)
    hsv = rgb_to_hsv(rgb)
    hsv[:, 0] = np.mod(hsv[:, 0] + (b[:, 0] - 128.0) / 256.0, 1.0)
    hsv[:, 1] = np.clip(hsv[:, 1] * b[:, 1] / 128.0, 0.0, 1.0)
    hsv[:, 2] = np.clip(hsv[:, 2] * b[:, 2] / 128.0, 0.0, 1.0)
    shifted = rgb + (hsv_to_rgb(hsv) - rgb) * mask
    pal = rgb + (b[:, :3] / 255.0 - rgb) * mask
    return np.where((b[:, 3] == MODE_HSV)[:, None], shifted, np.where((b[:, 3] == MODE_PALETTE)[:, None], pal, rgb))
