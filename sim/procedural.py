"""Procedural skinned characters: a humanoid and a quadruped, deterministic by seed.

Each body part is a closed lat-long tube (a capsule-like surface of revolution
with an elliptic cross-section) around one bone. The number of rings and
segments per part is chosen so that the whole character meets a requested
triangle count (500 ..= 200,000) within ``TRIANGLE_TOLERANCE``: every part gets
a share proportional to its surface area, and the largest part (the torso)
absorbs the remainder exactly (up to 2 triangles, a tube always has an even
count). Parts interpenetrate at the joints; each is watertight on its own.

Skin weights bind each part to its bone and blend smoothly (smoothstep) to the
parent bone near the part's start and to the child bone near its end, so a
vertex has at most three influences and its weights sum to 1.

Rest pose: every joint rotation is the identity, so bones point along the
offsets between joints and the joint frames are world aligned; inverse bind
matrices are the inverse rest globals (the bind pose reproduces the mesh).
Clips rotate joints about their local X axis (swing in the sagittal plane)
with small twists; they play in place (no root translation) and record their
natural ground speed in ``Clip.speed`` (foot travel during stance divided by
the stance time, measured by forward kinematics on the clip itself).

Coordinates: metres, Y up, characters face +Z, feet on y = 0.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim import math3d
from sim.character import SkinnedCharacter
from sim.clip import Channel, Clip
from sim.mesh import Mesh
from sim.skeleton import Skeleton

#: Relative tolerance on the requested triangle count.
TRIANGLE_TOLERANCE = 0.02
#: Accepted triangle counts.
TRIANGLES_MIN = 500
TRIANGLES_MAX = 200_000
#: Keys per cycle of the generated clips (LINEAR interpolation).
KEYS_PER_CYCLE = 32
#: Smallest tube: MIN_SEGMENTS around, MIN_BANDS pole to pole (2 * 4 * 2 = 16 triangles).
MIN_SEGMENTS = 4
MIN_BANDS = 3


# --------------------------------------------------------------------------- parts

@dataclass
class Part:
    """One body part: a closed tube around a bone.

    bone : joint index the part is bound to
    a, b : (3,) start / end of the tube axis at rest (metres)
    r0, r1 : radius at a and at b along ``hint`` (metres)
    ratio : radius across (perpendicular to hint and axis) / radius along hint
    hint : (3,) direction of the first cross-section axis (orthogonalised)
    color : (4,) linear RGBA
    parent : joint to blend with near ``a`` (-1: none)
    child : joint to blend with near ``b`` (-1: none)
    pad : how far the caps extend past a and b (metres)
    blend : length of the weight blend at each end (metres)
    roundness : exponent of the profile ``sin(pi v) ** roundness`` (< 1 = blunter caps)
    """

    bone: int
    a: np.ndarray
    b: np.ndarray
    r0: float
    r1: float
    ratio: float
    hint: np.ndarray
    color: np.ndarray
    parent: int = -1
    child: int = -1
    pad: float | None = None
    blend: float = 0.06
    roundness: float = 0.55

    @property
    def length(self) -> float:
        return float(np.linalg.norm(np.asarray(self.b) - np.asarray(self.a)))

    def area(self) -> float:
        r = 0.5 * (self.r0 + self.r1) * (1.0 + self.ratio) * 0.5
        return 2.0 * np.pi * r * (self.length + 2.0 * self._pad())

    def aspect(self) -> float:
        """Segments / bands giving roughly square quads."""
        r = 0.5 * (self.r0 + self.r1) * (1.0 + self.ratio) * 0.5
        meridian = self.length + 2.0 * self._pad() + 1e-9
        return float(np.clip(2.0 * np.pi * r / meridian, 0.25, 8.0)) * 2.0

    def _pad(self) -> float:
        return 0.8 * max(self.r0, self.r1) if self.pad is None else self.pad


def _resolution(tris: float, aspect: float) -> tuple[int, int]:
    """(segments M, bands L) with 2 M (L - 1) ~ tris and M / (L - 1) ~ aspect."""
    l1 = max(MIN_BANDS - 1, int(round(np.sqrt(max(tris, 1.0) / (2.0 * aspect)))))
    m = max(MIN_SEGMENTS, int(round(tris / (2.0 * l1))))
    return m, l1 + 1


def _fit_resolution(tris: int, aspect: float) -> tuple[int, int]:
    """(M, L) whose count 2 M (L - 1) is closest to ``tris`` (then closest to ``aspect``)."""
    best = None
    m_hi = max(MIN_SEGMENTS, int(tris // (2 * (MIN_BANDS - 1))))
    for m in range(MIN_SEGMENTS, m_hi + 1):
        for l1 in {max(MIN_BANDS - 1, tris // (2 * m)), max(MIN_BANDS - 1, tris // (2 * m) + 1)}:
            err = abs(2 * m * l1 - tris)
            shape = abs(np.log(m / l1 / aspect))
            key = (err, shape)
            if best is None or key < best[0]:
                best = (key, m, l1 + 1)
    return best[1], best[2]


def _tube(part: Part, m: int, l: int):
    """Vertices (V,3) float64, triangles (T,3) int64 with outward winding, axial
    distance from ``a`` (V,) and from ``b`` (V,) of one closed tube.

    V = 2 + (l - 1) m, T = 2 m (l - 1).
    """
    a = np.asarray(part.a, np.float64)
    b = np.asarray(part.b, np.float64)
    d = b - a
    length = np.linalg.norm(d)
    d = d / length
    e1 = np.asarray(part.hint, np.float64)
    e1 = e1 - np.dot(e1, d) * d
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    pad = part._pad()
    half = 0.5 * length + pad
    c = 0.5 * (a + b)

    v = np.arange(1, l) / l  # ring latitudes (excluding poles)
    x = -np.cos(np.pi * v)  # axial coordinate in [-1, 1]
    rad = np.sin(np.pi * v) ** part.roundness
    s = np.clip((x * half + 0.5 * length) / length, 0.0, 1.0)
    r = part.r0 + (part.r1 - part.r0) * s
    phi = 2.0 * np.pi * np.arange(m) / m
    cp, sp = np.cos(phi), np.sin(phi)
    ring_c = c + np.outer(x * half, d)  # (l-1, 3)
    rr = (rad * r)[:, None, None]
    offs = cp[None, :, None] * e1 + (sp[None, :, None] * part.ratio) * e2  # (1, m, 3)
    rings = ring_c[:, None, :] + rr * offs
    pts = np.concatenate([(c - half * d)[None], rings.reshape(-1, 3), (c + half * d)[None]])

    ring = lambda i, k: 1 + i * m + (k % m)  # noqa: E731
    k = np.arange(m)
    tris = []
    tris.append(np.stack([np.zeros(m, np.int64), ring(0, k + 1), ring(0, k)], 1))
    if l > 2:
        i = np.arange(l - 2)[:, None]
        aa, bb = ring(i, k), ring(i, k + 1)
        cc, dd = ring(i + 1, k), ring(i + 1, k + 1)
        tris.append(np.stack([aa, bb, cc], -1).reshape(-1, 3))
        tris.append(np.stack([bb, dd, cc], -1).reshape(-1, 3))
    last = pts.shape[0] - 1
    tris.append(np.stack([ring(l - 2, k), ring(l - 2, k + 1), np.full(m, last, np.int64)], 1))
    tri = np.concatenate(tris).astype(np.int64)
    t_a = (pts - a) @ d
    t_b = (b - pts) @ d
    return pts, tri, t_a, t_b


def _smoothstep(u):
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def _normals(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (V,3) float64 (bincount: fast for 10^5 triangles)."""
    fn = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
    n = np.zeros_like(p)
    idx = tri.reshape(-1)
    for c in range(3):
        w = np.repeat(fn[:, c], 3)
        n[:, c] = np.bincount(idx, weights=w, minlength=p.shape[0])
    return math3d.normalize_vectors(n)


def _allocate(parts: list, triangles: int) -> list:
    """(M, L) per part so that sum 2 M (L - 1) hits ``triangles`` (the largest part
    absorbs the remainder)."""
    areas = np.array([p.area() for p in parts])
    big = int(np.argmax(areas))
    factor = triangles / areas.sum()
    for _ in range(200):
        res = [_resolution(factor * ar, p.aspect()) for ar, p in zip(areas, parts)]
        counts = np.array([2 * m * (l - 1) for m, l in res])
        rest = triangles - (counts.sum() - counts[big])
        if rest >= max(2 * MIN_SEGMENTS * (MIN_BANDS - 1), 0.5 * factor * areas[big]):
            res[big] = _fit_resolution(int(rest), parts[big].aspect())
            return res
        factor *= 0.97
    raise ValueError(f"cannot distribute {triangles} triangles over {len(parts)} parts")


def _build_mesh(parts: list, triangles: int, skeleton: Skeleton, rng, jitter: float = 0.03,
                recolor=None) -> Mesh:
    """Tessellate, weight and colour all parts into one skinned Mesh."""
    res = _allocate(parts, triangles)
    P, I, N, C, JN, W = [], [], [], [], [], []
    base = 0
    for pi, (part, (m, l)) in enumerate(zip(parts, res)):
        pts, tri, t_a, t_b = _tube(part, m, l)
        V = pts.shape[0]
        nrm = _normals(pts, tri)
        blend = min(part.blend, 0.5 * part.length)
        wp = _smoothstep(0.5 - t_a / (2 * blend)) if part.parent >= 0 else np.zeros(V)
        wc = _smoothstep(0.5 - t_b / (2 * blend)) if part.child >= 0 else np.zeros(V)
        wj = np.clip(1.0 - wp - wc, 0.0, 1.0)
        w = np.stack([wj, wp, wc, np.zeros(V)], 1)
        w /= w.sum(1, keepdims=True)
        j = np.zeros((V, 4), np.int64)
        j[:, 0] = part.bone
        j[:, 1] = max(part.parent, 0)
        j[:, 2] = max(part.child, 0)
        col = np.tile(np.asarray(part.color, np.float64), (V, 1))
        if recolor is not None:
            col = recolor(pi, part, pts, col)
        col[:, :3] *= 1.0 + jitter * rng.uniform(-1.0, 1.0, size=(V, 1))
        P.append(pts), I.append(tri + base), N.append(nrm), C.append(col), JN.append(j), W.append(w)
        base += V
    colors = np.clip(np.concatenate(C), 0.0, 1.0)
    return Mesh(
        positions=np.concatenate(P).astype(np.float32),
        indices=np.concatenate(I).astype(np.uint32),
        normals=np.concatenate(N).astype(np.float32),
        colors=colors.astype(np.float32),
        joints=np.concatenate(JN).astype(np.uint16),
        weights=np.concatenate(W).astype(np.float32),
        double_sided=False,  # closed tubes wound counter-clockwise seen from outside (tests/sim/test_procedural.py)
    )


def _skeleton(names, parents, positions) -> Skeleton:
    parents = np.asarray(parents, np.int32)
    pos = np.asarray(positions, np.float64)
    local = pos.copy()
    local[parents >= 0] = pos[parents >= 0] - pos[parents[parents >= 0]]
    J = len(names)
    sk = Skeleton(
        names=list(names),
        parents=parents,
        rest_translation=local,
        rest_rotation=np.tile([0.0, 0.0, 0.0, 1.0], (J, 1)),
        rest_scale=np.ones((J, 3)),
        inverse_bind=np.tile(np.eye(4), (J, 1, 1)),
    )
    sk.inverse_bind = sk.rest_inverse_bind()
    return sk


def _check_triangles(triangles) -> int:
    if isinstance(triangles, bool) or not isinstance(triangles, (int, np.integer)) \
            or not TRIANGLES_MIN <= int(triangles) <= TRIANGLES_MAX:
        raise ValueError(f"triangles: expected an integer in {TRIANGLES_MIN}..={TRIANGLES_MAX}, got {triangles!r}")
    return int(triangles)


# --------------------------------------------------------------------------- gait curves

def _hip_flex(phase, amp, duty):
    """Hip flexion (rad, + = leg forward): linear from +amp to -amp during the
    stance fraction ``duty`` (constant foot speed on the ground), cosine back
    during the swing."""
    ph = np.mod(phase, 1.0)
    st = ph < duty
    out = np.empty_like(ph)
    out[st] = amp - 2.0 * amp * ph[st] / duty
    u = (ph[~st] - duty) / (1.0 - duty)
    out[~st] = -amp + 2.0 * amp * 0.5 * (1.0 - np.cos(np.pi * u))
    return out


def _knee_flex(phase, stance_amp, swing_amp, duty):
    """Knee flexion (rad, >= 0): a small bump during stance, a large one during swing."""
    ph = np.mod(phase, 1.0)
    st = ph < duty
    out = np.empty_like(ph)
    out[st] = stance_amp * np.sin(np.pi * ph[st] / duty)
    out[~st] = swing_amp * np.sin(np.pi * (ph[~st] - duty) / (1.0 - duty))
    return out


def _bump(phase, center, width):
    d = np.mod(phase - center + 0.5, 1.0) - 0.5
    return np.exp(-0.5 * (d / width) ** 2)


def _rot_channel(joint, times, angles_xyz) -> Channel:
    """Rotation keys from Euler angles (applied X, then Y, then Z: q = qz qy qx)."""
    ax, ay, az = (np.broadcast_to(np.asarray(a, np.float64), times.shape) for a in angles_xyz)
    qx = math3d.quat_from_axis_angle(np.array([1.0, 0, 0]), ax)
    qy = math3d.quat_from_axis_angle(np.array([0, 1.0, 0]), ay)
    qz = math3d.quat_from_axis_angle(np.array([0, 0, 1.0]), az)
    q = math3d.quat_multiply(qz, math3d.quat_multiply(qy, qx))
    # keep consecutive keys in the same hemisphere (cosmetic; slerp handles either)
    for i in range(1, q.shape[0]):
        if np.dot(q[i], q[i - 1]) < 0:
            q[i] = -q[i]
    return Channel(int(joint), "rotation", times.copy(), q, "LINEAR")


def _measure_speed(skeleton: Skeleton, clip: Clip, foot: int, duty: float, phase0: float) -> float:
    """Ground speed (m/s): backward travel of ``foot`` relative to the root during
    its stance (phase ``phase0`` .. ``phase0 + duty``) divided by the stance time."""
    T = clip.duration
    ts = np.array([phase0, phase0 + duty]) * T
    z = skeleton.joint_positions(*clip.sample_times(skeleton, ts))[:, foot, 2]
    return float(max(z[0] - z[1], 0.0) / (duty * T))


def _cycle(period):
    phase = np.linspace(0.0, 1.0, KEYS_PER_CYCLE + 1)
    return phase, phase * period


# --------------------------------------------------------------------------- humanoid

HUMANOID_JOINTS = [
    "hips", "spine", "chest", "neck", "head",
    "l_clavicle", "l_upper_arm", "l_forearm", "l_hand",
    "r_clavicle", "r_upper_arm", "r_forearm", "r_hand",
    "l_thigh", "l_shin", "l_foot", "l_toe",
    "r_thigh", "r_shin", "r_foot", "r_toe",
]

#: variation regions of the generated humanoid (``SkinnedCharacter.regions``), by vertex
HUMANOID_REGIONS = ("skin", "hair", "shirt", "trousers", "shoes")
SKIN_TONES = np.array([[0.93, 0.72, 0.58], [0.80, 0.56, 0.40], [0.62, 0.42, 0.28], [0.40, 0.26, 0.17], [0.98, 0.80, 0.68]])
HAIR = np.array([[0.08, 0.05, 0.03], [0.30, 0.18, 0.08], [0.75, 0.60, 0.30], [0.45, 0.12, 0.05], [0.55, 0.55, 0.55]])
TROUSERS = np.array([[0.10, 0.14, 0.30], [0.20, 0.20, 0.22], [0.35, 0.28, 0.18], [0.12, 0.25, 0.14], [0.50, 0.45, 0.38]])


def _hsv(h, s, v):
    k = np.mod(np.array([5.0, 3.0, 1.0]) + h * 6.0, 6.0)
    return v - v * s * np.clip(np.minimum(k, 4.0 - k), 0.0, 1.0)


def _rgba(rgb):
    return np.array([*np.asarray(rgb, np.float64)[:3], 1.0])


def humanoid(triangles: int = 5000, seed: int = 0) -> SkinnedCharacter:
    """A procedural skinned human, about 1.8 m tall, facing +Z, feet on y = 0.

    Parameters
    ----------
    triangles : int in 500 ..= 200,000; met within ``TRIANGLE_TOLERANCE``.
    seed : int; selects colours (skin, hair, shirt, trousers) and small
        proportion changes. Same seed, same character (bit for bit).

    Returns
    -------
    SkinnedCharacter with 21 joints (root "hips") and looping clips "walk" and
    "run" (in place; ``Clip.speed`` is the matching ground spee);
    ``regions`` maps each of HUMANOID_REGIONS to its vertices (bool mask).
    """
    triangles = _check_triangles(triangles)
    rng = np.random.default_rng([int(seed), 0x4855])
    h = rng.uniform(0.975, 1.025)  # height scale
    wd = rng.uniform(0.92, 1.08)  # width scale
    skin = _rgba(SKIN_TONES[rng.integers(len(SKIN_TONES))])
    hair = _rgba(HAIR[rng.integers(len(HAIR))])
    shirt = _rgba(_hsv(rng.uniform(), rng.uniform(0.35, 0.8), rng.uniform(0.45, 0.85)))
    trousers = _rgba(TROUSERS[rng.integers(len(TROUSERS))])
    shoes = _rgba([0.07, 0.06, 0.06] if rng.uniform() < 0.7 else [0.85, 0.85, 0.82])

    P = {}
    P["hips"] = (0, 0.95, 0)
    P["spine"] = (0, 1.07, 0)
    P["chest"] = (0, 1.29, 0)
    P["neck"] = (0, 1.51, 0)
    P["head"] = (0, 1.60, 0.01)
    for side, sx in (("l", 1.0), ("r", -1.0)):
        P[f"{side}_clavicle"] = (sx * 0.04 * wd, 1.46, 0)
        P[f"{side}_upper_arm"] = (sx * 0.19 * wd, 1.46, 0)
        P[f"{side}_forearm"] = (sx * 0.22 * wd, 1.18, -0.01)
        P[f"{side}_hand"] = (sx * 0.235 * wd, 0.93, 0.01)
        P[f"{side}_thigh"] = (sx * 0.095 * wd, 0.91, 0)
        P[f"{side}_shin"] = (sx * 0.10 * wd, 0.49, 0.01)
        P[f"{side}_foot"] = (sx * 0.10 * wd, 0.085, -0.01)
        P[f"{side}_toe"] = (sx * 0.10 * wd, 0.035, 0.13)
    pos = np.array([P[n] for n in HUMANOID_JOINTS], np.float64)
    pos[:, 1] *= h
    parents = [-1, 0, 1, 2, 3, 2, 5, 6, 7, 2, 9, 10, 11, 0, 13, 14, 15, 0, 17, 18, 19]
    sk = _skeleton(HUMANOID_JOINTS, parents, pos)
    J = {n: i for i, n in enumerate(HUMANOID_JOINTS)}
    X, Y = np.eye(3)[:2]

    def at(name, dy=0.0, dz=0.0, dx=0.0):
        return pos[J[name]] + (dx, dy * h, dz)

    parts = [
        Part(J["hips"], at("hips", -0.08), at("spine", 0.0), 0.165 * wd, 0.15 * wd, 0.72, X, trousers, child=J["spine"], pad=0.05, blend=0.05),
        Part(J["spine"], at("spine"), at("chest"), 0.15 * wd, 0.165 * wd, 0.68, X, shirt, parent=J["hips"], child=J["chest"], pad=0.04),
        Part(J["chest"], at("chest"), at("neck", -0.02), 0.175 * wd, 0.185 * wd, 0.62, X, shirt, parent=J["spine"], child=J["neck"], pad=0.05),
        Part(J["neck"], at("neck", -0.02), at("head"), 0.05, 0.048, 1.0, X, skin, parent=J["chest"], child=J["head"], pad=0.02, blend=0.03),
        Part(J["head"], at("head", 0.0, 0.0), at("head", 0.19, 0.005), 0.085, 0.08, 1.2, X, skin, parent=J["neck"], pad=0.035, blend=0.03, roundness=0.7),
    ]
    for side, sx in (("l", 1.0), ("r", -1.0)):
        s = lambda n: J[f"{side}_{n}"]  # noqa: E731
        sp = lambda n, **kw: at(f"{side}_{n}", **kw)  # noqa: E731
        parts += [
            Part(s("clavicle"), sp("clavicle"), sp("upper_arm"), 0.06, 0.06, 0.9, Y, shirt, parent=J["chest"], child=s("upper_arm"), pad=0.04, blend=0.04),
            Part(s("upper_arm"), sp("upper_arm"), sp("forearm"), 0.058, 0.046, 1.0, X, shirt, parent=s("clavicle"), child=s("forearm"), pad=0.03, blend=0.05),
            Part(s("forearm"), sp("forearm"), sp("hand"), 0.045, 0.034, 1.0, X, skin, parent=s("upper_arm"), child=s("hand"), pad=0.02, blend=0.05),
            Part(s("hand"), sp("hand"), sp("hand", dy=-0.17), 0.024, 0.02, 2.0, X, skin, parent=s("forearm"), pad=0.015, blend=0.03),
            Part(s("thigh"), sp("thigh"), sp("shin"), 0.088 * wd, 0.06, 1.0, X, trousers, parent=J["hips"], child=s("shin"), pad=0.04, blend=0.07),
            Part(s("shin"), sp("shin"), sp("foot"), 0.058, 0.042, 1.0, X, trousers, parent=s("thigh"), child=s("foot"), pad=0.03, blend=0.06),
            Part(s("foot"), sp("foot", dy=-0.04, dz=-0.06), sp("toe"), 0.045, 0.04, 0.9, X, shoes, child=s("toe"), pad=0.02, blend=0.03, roundness=0.5),
            Part(s("toe"), sp("toe"), sp("toe", dy=0.0, dz=0.08), 0.042, 0.038, 0.7, X, shoes, parent=s("foot"), pad=0.02, blend=0.02),
        ]
    head_c = 0.5 * (at("head") + at("head", 0.19))

    labels = []  # region index (HUMANOID_REGIONS) of every vertex, part by part

    def recolor(pi, part, pts, col):
        lab = np.full(pts.shape[0], next(k for k, c in enumerate((skin, hair, shirt, trousers, shoes))
                                         if c is part.color), np.int8)
        if part.bone == J["head"] and part is parts[4]:
            rel = pts - head_c
            face = (rel[:, 2] > 0.02) & (rel[:, 1] < 0.06 * h)
            hairy = (rel[:, 1] > -0.02) & ~face
            col[hairy] = hair
            lab[hairy] = 1
        labels.append(lab)
        return col

    mesh = _build_mesh(parts, triangles, sk, rng, recolor=recolor)
    lab = np.concatenate(labels)
    regions = {name: lab == k for k, name in enumerate(HUMANOID_REGIONS)}
    clips = {
        "walk": _humanoid_gait(sk, J, "walk", period=1.1, duty=0.62, hip=0.5, knee_st=0.18, knee_sw=1.05,
                               arm=0.38, elbow=0.3, lean=0.03, twist=0.07),
        "run": _humanoid_gait(sk, J, "run", period=0.72, duty=0.38, hip=0.62, knee_st=0.45, knee_sw=1.9,
                              arm=0.6, elbow=1.35, lean=0.16, twist=0.12),
    }
    return SkinnedCharacter(f"humanoid-{seed}", mesh, sk, clips, source=f"procedural:humanoid triangles={triangles} seed={seed}",
                            regions=regions)


def _humanoid_gait(sk, J, name, *, period, duty, hip, knee_st, knee_sw, arm, elbow, lean, twist) -> Clip:
    phase, times = _cycle(period)
    ch = []
    for side, off in (("l", 0.0), ("r", 0.5)):
        ph = phase + off
        flex = _hip_flex(ph, hip, duty)
        knee = _knee_flex(ph, knee_st, knee_sw, duty)
        foot = 0.35 * _bump(ph, duty, 0.07) - 0.15 * _bump(ph, 0.0, 0.06) - 0.25 * knee * (knee > knee_st) * 0.5
        ch.append(_rot_channel(J[f"{side}_thigh"], times, (-flex, 0.0, 0.0)))
        ch.append(_rot_channel(J[f"{side}_shin"], times, (knee, 0.0, 0.0)))
        ch.append(_rot_channel(J[f"{side}_foot"], times, (foot, 0.0, 0.0)))
        ch.append(_rot_channel(J[f"{side}_toe"], times, (-0.4 * _bump(ph, duty - 0.03, 0.06), 0.0, 0.0)))
        # the arm swings with the opposite leg
        swing = arm * np.cos(2.0 * np.pi * (ph - 0.5))
        sgn = 1.0 if side == "l" else -1.0
        ch.append(_rot_channel(J[f"{side}_upper_arm"], times, (-swing, 0.0, sgn * 0.06)))
        ch.append(_rot_channel(J[f"{side}_forearm"], times, (-(elbow + 0.25 * np.maximum(swing, 0.0)), 0.0, 0.0)))
    c = np.cos(2.0 * np.pi * phase)
    ch.append(_rot_channel(J["hips"], times, (0.0, twist * c, 0.02 * np.sin(2.0 * np.pi * phase))))
    ch.append(_rot_channel(J["spine"], times, (lean, -0.5 * twist * c, 0.0)))
    ch.append(_rot_channel(J["chest"], times, (0.3 * lean, -0.9 * twist * c, 0.0)))
    ch.append(_rot_channel(J["neck"], times, (-0.6 * lean, 0.5 * twist * c, 0.0)))
    ch.append(_rot_channel(J["head"], times, (-0.4 * lean + 0.02 * np.cos(4 * np.pi * phase), 0.4 * twist * c, 0.0)))
    clip = Clip(name, float(period), ch, loop=True)
    speeds = [_measure_speed(sk, clip, J[f"{s}_foot"], duty, (-off) % 1.0) for s, off in (("l", 0.0), ("r", 0.5))]
    clip.speed = float(np.mean(speeds))
    return clip


# --------------------------------------------------------------------------- quadruped

QUADRUPED_JOINTS = [
    "pelvis", "spine", "chest", "neck_1", "neck_2", "head", "tail_1", "tail_2", "tail_3",
    "lf_upper", "lf_fore", "lf_cannon", "lf_hoof",
    "rf_upper", "rf_fore", "rf_cannon", "rf_hoof",
    "lh_upper", "lh_gaskin", "lh_cannon", "lh_hoof",
    "rh_upper", "rh_gaskin", "rh_cannon", "rh_hoof",
]

COATS = np.array([[0.45, 0.27, 0.13], [0.30, 0.18, 0.10], [0.62, 0.42, 0.22], [0.55, 0.52, 0.50],
                  [0.12, 0.10, 0.09], [0.78, 0.70, 0.58], [0.55, 0.24, 0.10]])


def quadruped(triangles: int = 5000, seed: int = 0) -> SkinnedCharacter:
    """A procedural skinned four-legged animal (horse-like), facing +Z.

    About 1.6 m at the shoulder and 2.2 m long (nose to rump), hooves on y = 0.

    Parameters
    ----------
    triangles : int in 500 ..= 200,000; met within ``TRIANGLE_TOLERANCE``.
    seed : int; selects the coat colour (with per-vertex variation) and
        small proportion changes.

    Returns
    -------
    SkinnedCharacter with 25 joints (root "pelvis"; tail, neck and head
    chains) and looping clips "walk" (four-beat) and "gallop".
    """
    triangles = _check_triangles(triangles)
    rng = np.random.default_rng([int(seed), 0x5155])
    coat_rgb = COATS[rng.integers(len(COATS))] * rng.uniform(0.9, 1.1, 3)
    coat = _rgba(coat_rgb)
    legs = _rgba(coat_rgb * 0.55)
    hoof = _rgba([0.06, 0.05, 0.05])
    mane = _rgba(coat_rgb * 0.35)
    s = rng.uniform(0.96, 1.04)

    P = {
        "pelvis": (0, 1.30, -0.55), "spine": (0, 1.29, -0.05), "chest": (0, 1.30, 0.42),
        "neck_1": (0, 1.42, 0.68), "neck_2": (0, 1.64, 0.86), "head": (0, 1.80, 0.98),
        "tail_1": (0, 1.36, -0.84), "tail_2": (0, 1.20, -0.96), "tail_3": (0, 0.98, -1.02),
    }
    for side, sx in (("l", 1.0), ("r", -1.0)):
        P[f"{side}f_upper"] = (sx * 0.17, 1.22, 0.52)
        P[f"{side}f_fore"] = (sx * 0.19, 0.92, 0.47)
        P[f"{side}f_cannon"] = (sx * 0.19, 0.50, 0.49)
        P[f"{side}f_hoof"] = (sx * 0.19, 0.15, 0.48)
        P[f"{side}h_upper"] = (sx * 0.16, 1.22, -0.58)
        P[f"{side}h_gaskin"] = (sx * 0.19, 0.90, -0.45)
        P[f"{side}h_cannon"] = (sx * 0.19, 0.52, -0.66)
        P[f"{side}h_hoof"] = (sx * 0.19, 0.15, -0.62)
    pos = np.array([P[n] for n in QUADRUPED_JOINTS], np.float64) * s
    parents = [-1, 0, 1, 2, 3, 4, 0, 6, 7,
               2, 9, 10, 11, 2, 13, 14, 15,
               0, 17, 18, 19, 0, 21, 22, 23]
    sk = _skeleton(QUADRUPED_JOINTS, parents, pos)
    J = {n: i for i, n in enumerate(QUADRUPED_JOINTS)}
    X = np.eye(3)[0]
    at = lambda n, d=(0.0, 0.0, 0.0): pos[J[n]] + np.asarray(d) * s  # noqa: E731

    parts = [
        Part(J["pelvis"], at("pelvis", (0, 0, -0.27)), at("pelvis", (0, -0.01, 0.25)), 0.26, 0.29, 1.12, X, coat, child=J["spine"], pad=0.1, blend=0.1, roundness=0.4),
        Part(J["spine"], at("spine", (0, 0, -0.28)), at("spine", (0, 0, 0.25)), 0.29, 0.30, 1.1, X, coat, parent=J["pelvis"], child=J["chest"], pad=0.15, blend=0.1, roundness=0.25),
        Part(J["chest"], at("chest", (0, 0, -0.25)), at("chest", (0, 0.02, 0.3)), 0.30, 0.26, 1.15, X, coat, parent=J["spine"], child=J["neck_1"], pad=0.12, blend=0.1, roundness=0.4),
        Part(J["neck_1"], at("neck_1", (0, -0.05, -0.05)), at("neck_2"), 0.11, 0.10, 1.6, X, coat, parent=J["chest"], child=J["neck_2"], pad=0.08, blend=0.08),
        Part(J["neck_2"], at("neck_2"), at("head"), 0.09, 0.085, 1.5, X, coat, parent=J["neck_1"], child=J["head"], pad=0.06, blend=0.06),
        Part(J["head"], at("head", (0, 0.02, -0.04)), at("head", (0, -0.2, 0.32)), 0.085, 0.06, 1.5, X, coat, parent=J["neck_2"], pad=0.05, blend=0.05, roundness=0.6),
        Part(J["tail_1"], at("tail_1"), at("tail_2"), 0.045, 0.04, 1.0, X, mane, parent=J["pelvis"], child=J["tail_2"], pad=0.03, blend=0.04),
        Part(J["tail_2"], at("tail_2"), at("tail_3"), 0.06, 0.07, 1.0, X, mane, parent=J["tail_1"], child=J["tail_3"], pad=0.03, blend=0.04),
        Part(J["tail_3"], at("tail_3"), at("tail_3", (0, -0.3, -0.03)), 0.07, 0.04, 1.0, X, mane, parent=J["tail_2"], pad=0.03, blend=0.04),
    ]
    for side in ("l", "r"):
        for end, body in (("f", J["chest"]), ("h", J["pelvis"])):
            n = (lambda k, e=end, sd=side: f"{sd}{e}_{k}")
            mid = "fore" if end == "f" else "gaskin"
            j_up, j_mid, j_can, j_hoof = J[n("upper")], J[n(mid)], J[n("cannon")], J[n("hoof")]
            top = at(n("upper"), (0, 0.02, 0))
            parts += [
                Part(j_up, top, at(n(mid)), 0.13 if end == "f" else 0.16, 0.075, 0.9, X, coat, parent=body, child=j_mid, pad=0.05, blend=0.08),
                Part(j_mid, at(n(mid)), at(n("cannon")), 0.07, 0.05, 1.0, X, coat if end == "h" else legs, parent=j_up, child=j_can, pad=0.03, blend=0.06),
                Part(j_can, at(n("cannon")), at(n("hoof")), 0.042, 0.036, 1.1, X, legs, parent=j_mid, child=j_hoof, pad=0.03, blend=0.05),
                Part(j_hoof, at(n("hoof")), at(n("hoof"), (0, -0.15, 0.04)), 0.04, 0.06, 1.0, X, hoof, parent=j_can, pad=0.0, blend=0.04, roundness=0.3),
            ]

    def recolor(pi, part, pts, col):
        if part.bone in (J["neck_1"], J["neck_2"]):
            # a darker mane strip along the crest (upper-back side) of the neck
            d = math3d.normalize_vectors(np.asarray(part.b) - np.asarray(part.a))
            up = math3d.normalize_vectors(np.array([0.0, 0.3, -1.0]) - np.dot([0.0, 0.3, -1.0], d) * d)
            rel = pts - part.a
            rel = rel - np.outer(rel @ d, d)
            col[math3d.normalize_vectors(rel) @ up > 0.85] = mane
        return col

    mesh = _build_mesh(parts, triangles, sk, rng, jitter=0.05, recolor=recolor)
    clips = {
        "walk": _quadruped_gait(sk, J, "walk", period=1.15, duty=0.64, hip=0.32, knee=0.9,
                                offsets={"lh": 0.0, "lf": 0.25, "rh": 0.5, "rf": 0.75}, spine=0.03, neck=0.06),
        "gallop": _quadruped_gait(sk, J, "gallop", period=0.55, duty=0.3, hip=0.6, knee=1.5,
                                  offsets={"lh": 0.0, "rh": 0.1, "lf": 0.5, "rf": 0.6}, spine=0.1, neck=0.14),
    }
    return SkinnedCharacter(f"quadruped-{seed}", mesh, sk, clips, source=f"procedural:quadruped triangles={triangles} seed={seed}")


def _quadruped_gait(sk, J, name, *, period, duty, hip, knee, offsets, spine, neck) -> Clip:
    phase, times = _cycle(period)
    ch = []
    for leg, off in offsets.items():
        ph = phase + off
        flex = _hip_flex(ph, hip, duty)
        kn = _knee_flex(ph, 0.05, knee, duty)
        if leg.endswith("f"):
            ch.append(_rot_channel(J[f"{leg}_upper"], times, (-flex, 0.0, 0.0)))
            ch.append(_rot_channel(J[f"{leg}_fore"], times, (0.25 * kn, 0.0, 0.0)))
            ch.append(_rot_channel(J[f"{leg}_cannon"], times, (kn, 0.0, 0.0)))
        else:
            ch.append(_rot_channel(J[f"{leg}_upper"], times, (-flex, 0.0, 0.0)))
            ch.append(_rot_channel(J[f"{leg}_gaskin"], times, (-0.45 * kn, 0.0, 0.0)))
            ch.append(_rot_channel(J[f"{leg}_cannon"], times, (0.9 * kn, 0.0, 0.0)))
        ch.append(_rot_channel(J[f"{leg}_hoof"], times, (0.5 * kn, 0.0, 0.0)))
    w = 2.0 * np.pi * phase
    ch.append(_rot_channel(J["pelvis"], times, (spine * np.sin(w), 0.0, 0.3 * spine * np.sin(w))))
    ch.append(_rot_channel(J["spine"], times, (-spine * np.sin(w), 0.0, 0.0)))
    ch.append(_rot_channel(J["chest"], times, (-0.5 * spine * np.sin(w), 0.0, 0.0)))
    ch.append(_rot_channel(J["neck_1"], times, (neck * np.sin(2.0 * w if name == "walk" else w), 0.0, 0.0)))
    ch.append(_rot_channel(J["head"], times, (-0.5 * neck * np.sin(2.0 * w if name == "walk" else w), 0.0, 0.0)))
    for k, tj in enumerate(("tail_1", "tail_2", "tail_3")):
        ch.append(_rot_channel(J[tj], times, (0.1 * np.sin(w - k), 0.15 * np.sin(w - 0.7 * k), 0.0)))
    clip = Clip(name, float(period), ch, loop=True)
    speeds = [_measure_speed(sk, clip, J[f"{leg}_hoof"], duty, (-off) % 1.0) for leg, off in offsets.items()]
    clip.speed = float(np.mean(speeds))
    return clip


GENERATORS = {"humanoid": humanoid, "quadruped": quadruped}


def varied_clip(character: SkinnedCharacter, duration: float, seed: int = 0, name: str = "varied",
                sources: tuple | None = None) -> Clip:
    """A long looping clip that never repeats: sections of 2-5 s, each playing one of the character's own
    clips (``sources``, default all) time-warped to 0.5-1.6x speed, keyed at 30 Hz for every joint
    (translation and rotation, LINEAR). Deterministic for a seed. For clips of any length (tests of long
    clips; the pose count of mode points, ``lod.points.poses``).
    """
    d = float(duration)
    if not (d > 0.0) or not np.isfinite(d):
        raise ValueError(f"varied_clip: expected a positive duration, got {duration!r}")
    names = list(sources) if sources else list(character.clips)
    if not names:
        raise ValueError(f"varied_clip: character {character.name!r} has no clip to vary")
    rng = np.random.default_rng(seed)
    times = np.arange(0.0, d, 1.0 / 30.0)
    which, rate, t_end = np.zeros(times.size, np.int64), np.zeros(times.size), 0.0
    while t_end < d:
        n = rng.uniform(2.0, 5.0)
        sel = (times >= t_end) & (times < t_end + n)
        which[sel], rate[sel] = rng.integers(0, len(names)), rng.uniform(0.5, 1.6)
        t_end += n
    phase = np.concatenate([[0.0], np.cumsum(rate[:-1] / 30.0)])
    J = character.skeleton.n_joints
    T, R = np.empty((times.size, J, 3)), np.empty((times.size, J, 4))
    for c, cn in enumerate(names):
        m = which == c
        if m.any():
            src = character.clips[cn]
            T[m], R[m], _ = src.sample_times(character.skeleton, phase[m])  # phase: seconds of the source clip
    chans = []
    for j in range(J):
        chans.append(Channel(j, "translation", times.copy(), T[:, j].copy()))
        chans.append(Channel(j, "rotation", times.copy(), R[:, j].copy()))
    return Clip(name, d, chans, loop=True)
