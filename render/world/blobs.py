"""Blob shadows of many agents (:mod:`render.world.shadows`, mode "blob"): their instance rows in numba, and only
those that can cover a pixel.

:func:`blob_rows` is :func:`render.world.shadows.blob_instances` (the numpy reference, tested equal) as two
passes over flat arrays: the floor point and radius of every agent in parallel, then a serial pass that
keeps an agent's first row (an agent in two batches of a screen-door transition gets one blob) and drops
non-finite ones.

:func:`covering` keeps the blobs whose quad can cover a pixel centre. A blob is a quad of side twice its
radius lying at the agent's floor point; seen from far (a million agents over two kilometres: most are a
pixel or two tall) the quad is a fraction of a pixel and usually covers no pixel centre at all, so the
rasteriser makes no fragment of it and the image does not depend on it. The test is conservative: the
quad's window-space bounding box, computed in float64 from the same float32 inputs the vertex shader
reads, grown by :data:`COVER_MARGIN` pixels (far above llvmpipe's 1/256-pixel vertex snapping and the
shader's float32 rounding), must contain a pixel centre inside the viewport; and for a small quad one of
those centres must see the quad's plane inside its disc (the fragment shader discards where the blob's
opacity is 0, outside the disc inscribed in the quad), the disc grown by the same margin in pixels. A quad
with a corner at or behind the camera plane is always kept (clipping). With multisampling (coverage at sample positions, not
pixel centres) nothing is dropped. The image is identical (tests/render/test_blobs.py); the vertex stage,
single-threaded in llvmpipe, runs for the covering blobs only.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

#: pixels the window-space box (and the disc) of a blob quad is grown by before testing it for pixel centres
COVER_MARGIN = 0.05
#: a quad whose grown box holds at most this many pixel centres is tested centre by centre against its disc
#: (the fragment shader discards outside it); a larger one is kept
DISC_CANDIDATES = 16


@njit(cache=True, parallel=True)
def _rows_kernel(data, fp, out):  # pragma: no cover - compiled
    """(floor point, radius) of every row: ``m[:, :3] @ fp[:3] + m[:, 3]`` and ``fp[3] * |m[:, 0]|``
    with the model rows m of the instance data, in float64 as the reference computes them."""
    for i in prange(data.shape[0]):
        for a in range(3):
            s = 0.0
            s += np.float64(data[i, 4 * a]) * fp[0]
            s += np.float64(data[i, 4 * a + 1]) * fp[1]
            s += np.float64(data[i, 4 * a + 2]) * fp[2]
            out[i, a] = s + np.float64(data[i, 4 * a + 3])
        x, y, z = np.float64(data[i, 0]), np.float64(data[i, 4]), np.float64(data[i, 8])
        out[i, 3] = fp[3] * np.sqrt(x * x + y * y + z * z)


@njit(cache=True)
def _first_finite(ids, rows, seen, out):  # pragma: no cover - compiled
    """The rows of agents seen for the first time (ids >= 0), in order, the non-finite ones dropped
    after that (as the reference: a non-finite first row leaves the agent without a blob)."""
    n = 0
    for i in range(ids.shape[0]):
        a = ids[i]
        if a < 0 or seen[a]:
            continue
        seen[a] = True
        ok = True
        for c in range(4):
            if not np.isfinite(rows[i, c]):
                ok = False
        if ok:
            for c in range(4):
                out[n, c] = np.float32(rows[i, c])
            n += 1
    return n


def blob_rows(batches, footprints: dict) -> np.ndarray:
    """:func:`render.world.shadows.blob_instances` (same rows, same order) in numba."""
    parts = []
    for b in batches:
        fp = footprints.get(b.rep)
        iid = np.asarray(b.instance_ids)
        if fp is None or iid.size == 0:
            continue
        d = np.ascontiguousarray(b.instance_data).reshape(-1, 16)
        if d.dtype not in (np.float32, np.float64):
            d = d.astype(np.float64)
        rows = np.empty((d.shape[0], 4))
        _rows_kernel(d, np.asarray(fp[:4], np.float64), rows)
        parts.append((iid, rows))
    if not parts:
        return np.zeros((0, 4), np.float32)
    ids = np.concatenate([p[0] for p in parts]).astype(np.int64) if len(parts) > 1 else parts[0][0].astype(np.int64)
    rows = np.concatenate([p[1] for p in parts]) if len(parts) > 1 else parts[0][1]
    out = np.empty((ids.shape[0], 4), np.float32)
    seen = np.zeros(int(ids.max()) + 1 if ids.size and ids.max() >= 0 else 1, np.bool_)
    n = _first_finite(ids, rows, seen, out)
    return out[:n]


@njit(cache=True, parallel=True)
def _cover_kernel(blobs, vp, lift, w, h, margin, keep):  # pragma: no cover - compiled
    for i in prange(blobs.shape[0]):
        fx, fy, fz, r = (np.float64(blobs[i, 0]), np.float64(blobs[i, 1]) + lift, np.float64(blobs[i, 2]),
                         np.float64(blobs[i, 3]))
        x0, y0 = np.inf, np.inf
        x1, y1 = -np.inf, -np.inf
        clipped = False
        for c in range(4):
            px = fx + (1.0 if c & 1 else -1.0) * r
            pz = fz + (1.0 if c & 2 else -1.0) * r
            cw = vp[3, 0] * px + vp[3, 1] * fy + vp[3, 2] * pz + vp[3, 3]
            if not cw > 1e-6:
                clipped = True
                break
            sx = ((vp[0, 0] * px + vp[0, 1] * fy + vp[0, 2] * pz + vp[0, 3]) / cw * 0.5 + 0.5) * w
            sy = ((vp[1, 0] * px + vp[1, 1] * fy + vp[1, 2] * pz + vp[1, 3]) / cw * 0.5 + 0.5) * h
            x0, x1 = min(x0, sx), max(x1, sx)
            y0, y1 = min(y0, sy), max(y1, sy)
        if clipped:
            keep[i] = True
            continue
        # pixel centres k + 0.5 inside [x0 - margin, x1 + margin] x [y0 - margin, y1 + margin], in the viewport
        kx0 = max(np.ceil(x0 - margin - 0.5), 0.0)
        kx1 = min(np.floor(x1 + margin - 0.5), w - 1.0)
        ky0 = max(np.ceil(y0 - margin - 0.5), 0.0)
        ky1 = min(np.floor(y1 + margin - 0.5), h - 1.0)
        if not (kx0 <= kx1 and ky0 <= ky1):
            keep[i] = False
            continue
        if (kx1 - kx0 + 1.0) * (ky1 - ky0 + 1.0) > DISC_CANDIDATES:
            keep[i] = True
            continue
        # a few candidate centres: is one of them inside the disc the fragment shader keeps (|q| < 1)?
        # clip(q) = c0 + qx * ax + qz * az (the quad is planar); at a centre with NDC (nx, ny) the two
        # equations clip.x = nx clip.w and clip.y = ny clip.w give q (a 2 x 2 solve); the disc is grown
        # by ``margin`` pixels through the inverse Jacobian of the map
        c0x = vp[0, 0] * fx + vp[0, 1] * fy + vp[0, 2] * fz + vp[0, 3]
        c0y = vp[1, 0] * fx + vp[1, 1] * fy + vp[1, 2] * fz + vp[1, 3]
        c0w = vp[3, 0] * fx + vp[3, 1] * fy + vp[3, 2] * fz + vp[3, 3]
        axx, axy, axw = vp[0, 0] * r, vp[1, 0] * r, vp[3, 0] * r
        azx, azy, azw = vp[0, 2] * r, vp[1, 2] * r, vp[3, 2] * r
        hit = False
        ky = ky0
        while ky <= ky1 and not hit:
            ny = 2.0 * (ky + 0.5) / h - 1.0
            kx = kx0
            while kx <= kx1:
                nx = 2.0 * (kx + 0.5) / w - 1.0
                a11 = axx - nx * axw
                a12 = azx - nx * azw
                a21 = axy - ny * axw
                a22 = azy - ny * azw
                b1 = -(c0x - nx * c0w)
                b2 = -(c0y - ny * c0w)
                det = a11 * a22 - a12 * a21
                if not abs(det) > 1e-300:
                    hit = True
                    break
                qx = (b1 * a22 - a12 * b2) / det
                qz = (a11 * b2 - b1 * a21) / det
                cw = c0w + qx * axw + qz * azw
                # d(ndc)/dq = A / cw; d(pixel)/d(ndc) = (w / 2, h / 2): pixel -> q scale of the inverse
                inv = abs(cw) * np.sqrt((a22 * a22 + a12 * a12) * (2.0 / w) ** 2
                                        + (a21 * a21 + a11 * a11) * (2.0 / h) ** 2) / abs(det)
                rad = 1.0 + margin * inv
                if qx * qx + qz * qz < rad * rad:
                    hit = True
                    break
                kx += 1.0
            ky += 1.0
        keep[i] = hit


def covering(blobs: np.ndarray, view_proj, size, lift: float, margin: float = COVER_MARGIN) -> np.ndarray:
    """(n,) bool: the blobs (rows of :func:`blob_rows`) whose quad may cover a pixel centre of a
    ``size`` viewport under ``view_proj`` (module docstring); non-finite ones are kept."""
    keep = np.empty(blobs.shape[0], np.bool_)
    vp = np.asarray(view_proj, np.float32).astype(np.float64)  # the shader's float32 matrix
    _cover_kernel(np.ascontiguousarray(blobs, np.float32), vp, float(np.float32(lift)), float(size[0]),
                  float(size[1]), float(margin), keep)
    return keep


__all__ = ["COVER_MARGIN", "blob_rows", "covering"]
