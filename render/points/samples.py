"""The point drawer's sample words (``render/points/draw.py``, which re-exports these): positions
quantised to unorm16 in a representation's box (folded into each instance's matrix), colours RGBA8, normals
octahedral snorm16x2 (``shaders/points/points_common.glsl``, ``points_placed.glsl``)."""
from __future__ import annotations

import numpy as np

#: bytes per sample (point or vertex): uvec4 geo, uvec4 attr (points_common.glsl)
SAMPLE_BYTES = 32
#: 32-bit words per sample
SAMPLE_WORDS = SAMPLE_BYTES // 4


def sample_box(*positions) -> tuple[np.ndarray, float]:
    """(lo (3,) float64, scale float > 0): the cube [lo, lo + scale]^3 holding
    every finite row of the given (n, 3) position arrays, in which
    :func:`pack_samples` quantises them (uniform scale, so normals transformed
    by the folded instance matrix keep their directions)."""
    ps = [np.asarray(p, np.float64).reshape(-1, 3) for p in positions]
    ps = [p[np.isfinite(p).all(axis=1)] for p in ps]
    ps = [p for p in ps if p.shape[0]]
    if not ps:
        return np.zeros(3), 1.0
    lo = np.min([p.min(axis=0) for p in ps], axis=0)
    hi = np.max([p.max(axis=0) for p in ps], axis=0)
    ext = float((hi - lo).max())
    return lo, (ext if ext > 0.0 and np.isfinite(ext) else 1.0)


def oct_encode(n: np.ndarray) -> np.ndarray:
    """(n, 2) float64 octahedral coordinates in [-1, 1] of (n, 3) directions
    (zero or non-finite ones give +z); decoded by ``oct_decode`` in
    points_common.glsl."""
    v = np.nan_to_num(np.asarray(n, np.float64).reshape(-1, 3), nan=0.0, posinf=0.0, neginf=0.0)
    l1 = np.abs(v).sum(axis=1)
    zero = l1 <= 1e-30
    v = np.where(zero[:, None], [0.0, 0.0, 1.0], v) / np.where(zero, 1.0, l1)[:, None]
    e = v[:, :2].copy()
    neg = v[:, 2] < 0.0
    sgn = np.where(e[neg] >= 0.0, 1.0, -1.0)
    e[neg] = (1.0 - np.abs(v[neg][:, [1, 0]])) * sgn
    return np.clip(e, -1.0, 1.0)


def pack_samples(p0, p1, n0, n1, c0, c1, lo=(0.0, 0.0, 0.0), scale=1.0) -> np.ndarray:
    """(n, 8) uint32 words of samples in the ``Sample`` layout: positions as
    unorm16 of ``(p - lo) / scale`` (:func:`sample_box`; error at most
    scale / 131070 per axis), colours RGBA8, normals octahedral snorm16x2.

    Non-finite inputs are replaced by 0 (nothing non-finite reaches the GPU).
    """
    n = np.asarray(p0).shape[0]
    out = np.zeros((n, 8), np.uint32)

    def unorm16(p):
        q = (np.asarray(p, np.float64).reshape(-1, 3) - np.asarray(lo, np.float64)) / float(scale)
        q = np.clip(np.nan_to_num(q, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
        return np.rint(q * 65535.0).astype(np.uint32)

    a, b = unorm16(p0), unorm16(p1)
    out[:, 0] = a[:, 0] | (a[:, 1] << 16)
    out[:, 1] = a[:, 2] | (b[:, 0] << 16)
    out[:, 2] = b[:, 1] | (b[:, 2] << 16)
    out[:, 4] = rgba8_words(c0)
    out[:, 5] = rgba8_words(c1)
    out[:, 6] = oct_words(n0)
    out[:, 7] = oct_words(n1)
    return out


def rgba8_words(c) -> np.ndarray:
    """(n,) uint32 RGBA8 words of (n, 4) colours in [0, 1] (clipped; NaN as 0), as GLSL packUnorm4x8."""
    c = np.nan_to_num(np.clip(np.asarray(c, np.float64).reshape(-1, 4), 0.0, 1.0))
    b = np.rint(c * 255.0).astype(np.uint32)
    return b[:, 0] | (b[:, 1] << 8) | (b[:, 2] << 16) | (b[:, 3] << 24)


def oct_words(v) -> np.ndarray:
    """(n,) uint32 octahedral snorm16x2 words of (n, 3) directions (:func:`oct_encode`; ``oct_decode`` in
    shaders/points/points_placed.glsl reads them)."""
    q = np.rint(oct_encode(v) * 32767.0).astype(np.int16).view(np.uint16).astype(np.uint32)
    return q[:, 0] | (q[:, 1] << 16)


def unpack_samples(words: np.ndarray, lo=(0.0, 0.0, 0.0), scale=1.0) -> dict:
    """Numpy decoding of :func:`pack_samples` words, as ``sample_at`` in
    points_common.glsl reads them: dict of p0, p1 (model frame), n0, n1
    (unit), c0, c1 (RGBA in [0, 1])."""
    w = np.asarray(words, np.uint32).reshape(-1, SAMPLE_WORDS)
    lo16 = (w & 0xFFFF).astype(np.float64) / 65535.0
    hi16 = (w >> 16).astype(np.float64) / 65535.0
    lo, scale = np.asarray(lo, np.float64), float(scale)
    p0 = np.stack([lo16[:, 0], hi16[:, 0], lo16[:, 1]], axis=1) * scale + lo
    p1 = np.stack([hi16[:, 1], lo16[:, 2], hi16[:, 2]], axis=1) * scale + lo

    def octd(col):
        e = np.stack([(w[:, col] & 0xFFFF).astype(np.uint16).view(np.int16),
                      (w[:, col] >> 16).astype(np.uint16).view(np.int16)], axis=1) / 32767.0
        e = np.clip(e, -1.0, 1.0)
        v = np.concatenate([e, 1.0 - np.abs(e).sum(axis=1, keepdims=True)], axis=1)
        neg = v[:, 2] < 0.0
        v[neg, :2] = (1.0 - np.abs(v[neg][:, [1, 0]])) * np.where(v[neg, :2] >= 0.0, 1.0, -1.0)
        return v / np.linalg.norm(v, axis=1, keepdims=True)

    def rgba(col):
        return np.stack([(w[:, col] >> (8 * k)) & 0xFF for k in range(4)], axis=1) / 255.0

    return {"p0": p0, "p1": p1, "n0": octd(6), "n1": octd(7), "c0": rgba(4), "c1": rgba(5)}


def fold_box(rows: np.ndarray, lo, scale: float) -> np.ndarray:
    """(k, 16) float32 instance rows whose model part also maps the box
    coordinates of :func:`pack_samples` to the model frame:
    M' = M · [scale I | lo]."""
    r = np.array(rows, np.float64).reshape(-1, 16)
    lo = np.asarray(lo, np.float64)
    for i in range(3):
        m = r[:, 4 * i:4 * i + 3]
        r[:, 4 * i + 3] += m @ lo
        r[:, 4 * i:4 * i + 3] = m * float(scale)
    return r.astype(np.float32)
