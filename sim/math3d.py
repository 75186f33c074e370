"""Small 3D math kernel: quaternions, TRS matrices, affine inverses.

Conventions (shared with glTF and the rest of ``sim``):

- quaternions are stored ``(x, y, z, w)``, unit length, Hamilton product,
  rotating column vectors: ``v' = q v q*``;
- matrices are 4x4 for column vectors (``p' = M @ p``), translation in
  ``M[:3, 3]``;
- every function is vectorised over leading axes (``...``) and works in
  float64; none returns NaN for degenerate input (zero quaternions become the
  identity, singular matrices fall back to documented values).
"""
from __future__ import annotations

import numpy as np

#: Below this squared norm a quaternion is treated as zero (-> identity).
QUAT_EPS2 = 1e-24
#: Above this cosine two rotations are treated as equal in slerp (-> nlerp).
SLERP_LINEAR_COS = 0.9995

IDENTITY_QUAT = np.array([0.0, 0.0, 0.0, 1.0])


def _f64(a) -> np.ndarray:
    return np.asarray(a, dtype=np.float64)


def quat_identity(shape=()) -> np.ndarray:
    """Identity quaternions, ``shape + (4,)`` float64."""
    shape = (shape,) if isinstance(shape, (int, np.integer)) else tuple(shape)
    q = np.zeros(shape + (4,), np.float64)
    q[..., 3] = 1.0
    return q


def quat_normalize(q) -> np.ndarray:
    """Unit quaternions, ``(..., 4)`` float64.

    Zero (or non-finite) quaternions become the identity, never NaN.
    """
    q = _f64(q)
    n2 = np.sum(q * q, axis=-1, keepdims=True)
    ok = np.isfinite(n2) & (n2 > QUAT_EPS2)
    safe = np.where(ok, n2, 1.0)
    out = np.where(ok, q / np.sqrt(safe), IDENTITY_QUAT)
    return out


def quat_multiply(a, b) -> np.ndarray:
    """Hamilton product ``a * b`` (apply b, then a), ``(..., 4)`` float64 (broadcasts)."""
    a = _f64(a)
    b = _f64(b)
    ax, ay, az, aw = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx, by, bz, bw = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=-1,
    )


def quat_conjugate(q) -> np.ndarray:
    """Conjugate (the inverse of a unit quaternion), ``(..., 4)`` float64."""
    q = _f64(q).copy()
    q[..., :3] *= -1.0
    return q


def quat_rotate(q, v) -> np.ndarray:
    """Rotate vectors ``v`` (..., 3) by unit quaternions ``q`` (..., 4); broadcasts."""
    q = _f64(q)
    v = _f64(v)
    u = q[..., :3]
    w = q[..., 3:4]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def quat_from_axis_angle(axis, angle) -> np.ndarray:
    """Quaternion of a rotation by ``angle`` radians about ``axis``.

    axis : (..., 3), need not be unit; a zero axis gives the identity.
    angle : (...,) radians.
    Returns (..., 4) float64.
    """
    axis = _f64(axis)
    angle = _f64(angle)
    n = np.linalg.norm(axis, axis=-1, keepdims=True)
    ok = n > 1e-300
    unit = np.where(ok, axis / np.where(ok, n, 1.0), 0.0)
    half = 0.5 * angle[..., None]
    q = np.concatenate([unit * np.sin(half), np.cos(half) * np.ones_like(n)], axis=-1)
    return np.where(ok, q, IDENTITY_QUAT)


def quat_to_axis_angle(q) -> tuple[np.ndarray, np.ndarray]:
    """Axis (..., 3) unit and angle (...,) in [0, pi] of unit quaternions.

    The identity gives axis (1, 0, 0) and angle 0.
    """
    q = quat_normalize(q)
    q = np.where(q[..., 3:4] < 0.0, -q, q)  # angle in [0, pi]
    s = np.linalg.norm(q[..., :3], axis=-1)
    angle = 2.0 * np.arctan2(s, q[..., 3])
    ok = s > 1e-12
    axis = np.where(ok[..., None], q[..., :3] / np.where(ok, s, 1.0)[..., None], np.array([1.0, 0.0, 0.0]))
    return axis, angle


def quat_slerp(a, b, t) -> np.ndarray:
    """Spherical linear interpolation along the shortest arc.

    Parameters
    ----------
    a, b : (..., 4) quaternions (normalised internally; broadcast together).
    t : (...,) or scalar, interpolation parameter, 0 -> a, 1 -> b.

    Returns
    -------
    (..., 4) float64 unit quaternions.

    Notes
    -----
    ``b`` is negated when ``dot(a, b) < 0`` so the path is the shortest one
    (q and -q are the same rotation). Nearly equal rotations
    (cos > ``SLERP_LINEAR_COS``) use normalised lerp, which avoids dividing by
    ``sin(theta) ~ 0``. Exactly opposite rotations on the 4-sphere cannot
    occur after the sign flip (their dot would be -1 -> flipped to +1); a 180
    degree *rotation* difference has dot 0 and is handled by plain slerp.
    """
    a = quat_normalize(a)
    b = quat_normalize(b)
    t = _f64(t)[..., None]
    d = np.sum(a * b, axis=-1, keepdims=True)
    b = np.where(d < 0.0, -b, b)
    d = np.abs(d)
    d = np.minimum(d, 1.0)
    lin = d > SLERP_LINEAR_COS
    theta = np.arccos(d)
    s = np.sin(theta)
    s_safe = np.where(lin, 1.0, s)
    wa = np.where(lin, 1.0 - t, np.sin((1.0 - t) * theta) / s_safe)
    wb = np.where(lin, t, np.sin(t * theta) / s_safe)
    return quat_normalize(wa * a + wb * b)


def quat_to_matrix(q) -> np.ndarray:
    """Rotation matrices (..., 3, 3) float64 of quaternions (normalised first)."""
    q = quat_normalize(q)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    m = np.empty(q.shape[:-1] + (3, 3), np.float64)
    m[..., 0, 0] = 1.0 - 2.0 * (yy + zz)
    m[..., 0, 1] = 2.0 * (xy - wz)
    m[..., 0, 2] = 2.0 * (xz + wy)
    m[..., 1, 0] = 2.0 * (xy + wz)
    m[..., 1, 1] = 1.0 - 2.0 * (xx + zz)
    m[..., 1, 2] = 2.0 * (yz - wx)
    m[..., 2, 0] = 2.0 * (xz - wy)
    m[..., 2, 1] = 2.0 * (yz + wx)
    m[..., 2, 2] = 1.0 - 2.0 * (xx + yy)
    return m


def matrix_to_quat(m) -> np.ndarray:
    """Quaternions (..., 4) of rotation matrices (..., 3, 3) (or the 3x3 block of 4x4).

    Shepperd's method (branch on the largest diagonal term), so no precision
    loss near 180 degrees. Result has w >= 0.
    """
    m = _f64(m)[..., :3, :3]
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    tr = m00 + m11 + m22
    cands = np.stack(
        [
            np.stack([m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1], 1.0 + tr], -1),
            np.stack([1.0 + m00 - m11 - m22, m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0], m[..., 2, 1] - m[..., 1, 2]], -1),
            np.stack([m[..., 0, 1] + m[..., 1, 0], 1.0 - m00 + m11 - m22, m[..., 1, 2] + m[..., 2, 1], m[..., 0, 2] - m[..., 2, 0]], -1),
            np.stack([m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1.0 - m00 - m11 + m22, m[..., 1, 0] - m[..., 0, 1]], -1),
        ],
        axis=-2,
    )
    key = np.stack([tr, m00, m11, m22], -1)
    best = np.argmax(key, axis=-1)
    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]
    q = quat_normalize(q)
    return np.where(q[..., 3:4] < 0.0, -q, q)


def trs_matrix(translation, rotation, scale) -> np.ndarray:
    """Compose ``T @ R @ S`` as (..., 4, 4) float64 (glTF node order).

    translation : (..., 3); rotation : (..., 4) (x, y, z, w); scale : (..., 3).
    Leading axes broadcast.
    """
    t = _f64(translation)
    r = quat_to_matrix(rotation)
    s = _f64(scale)
    shape = np.broadcast_shapes(t.shape[:-1], r.shape[:-2], s.shape[:-1])
    m = np.zeros(shape + (4, 4), np.float64)
    m[..., :3, :3] = r * s[..., None, :]
    m[..., :3, 3] = t
    m[..., 3, 3] = 1.0
    return m


def translation_matrix(t) -> np.ndarray:
    """(..., 4, 4) float64 translation matrices of (..., 3) offsets."""
    t = _f64(t)
    m = np.zeros(t.shape[:-1] + (4, 4), np.float64)
    m[..., 0, 0] = m[..., 1, 1] = m[..., 2, 2] = m[..., 3, 3] = 1.0
    m[..., :3, 3] = t
    return m


def invert_affine(m) -> np.ndarray:
    """Inverse of affine 4x4 matrices (..., 4, 4) float64 (last row 0 0 0 1).

    Singular linear parts are inverted with the pseudo-inverse (never NaN).
    """
    m = _f64(m)
    a = m[..., :3, :3]
    det = np.linalg.det(a)
    ok = np.abs(det) > 1e-300
    if np.all(ok):
        ai = np.linalg.inv(a)
    else:
        ai = np.linalg.pinv(a)
    out = np.zeros_like(m)
    out[..., :3, :3] = ai
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", ai, m[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def cofactor3(a) -> np.ndarray:
    """Cofactor matrices (..., 3, 3) of (..., 3, 3): ``det(A) * inv(A).T``.

    Defined (and finite) for singular matrices too, which makes it the safe way
    to transform normals: ``n' ~ cofactor(A) @ n`` up to the sign of det(A).
    """
    a = _f64(a)
    c0 = np.cross(a[..., :, 1], a[..., :, 2])
    c1 = np.cross(a[..., :, 2], a[..., :, 0])
    c2 = np.cross(a[..., :, 0], a[..., :, 1])
    return np.stack([c0, c1, c2], axis=-1)


def normalize_vectors(v, fallback=(0.0, 1.0, 0.0)) -> np.ndarray:
    """Unit vectors (..., 3) float64; zero or non-finite rows become ``fallback``."""
    v = _f64(v)
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    ok = np.isfinite(n) & (n > 1e-30)
    return np.where(ok, v / np.where(ok, n, 1.0), np.asarray(fallback, np.float64))
