"""The journeys' numba kernels against their plain references: nearest points and insideness, door
crossings (PedPy's definition), desired velocities, the kinematic move; slot layouts."""
import math

import numpy as np
import pytest

from sim.journeys.geometry import (Shapes, crossed_one, grid_in_polygon, nearest, nearest_reference,
                                   polyline_slots, sample_polygon)
from sim.journeys.steer import (HOLD, IDLE, LEAVING, PENDING, WALK, StraightRouter, desired_kernel,
                                desired_reference, move_kernel, move_reference)

L_SHAPE = [[0.0, 0.0], [4.0, 0.0], [4.0, 1.0], [1.0, 1.0], [1.0, 3.0], [0.0, 3.0]]


def _shapes(offset=0.0):
    s = Shapes()
    o = np.array([offset, -offset])
    s.add("point", [np.array([2.0, 5.0]) + o])
    s.add("polygon", np.asarray(L_SHAPE) + o)
    s.add("line", np.array([[-3.0, -1.0], [-3.0, 1.0]]) + o)
    s.add("line", np.array([[6.0, 6.0], [6.0, 6.0]]) + o)  # degenerate door (narrower than two radii)
    return s


@pytest.mark.parametrize("offset", [0.0, 1e6])
def test_nearest_matches_reference(offset):
    s = _shapes(offset)
    kind, start, verts = s.arrays()
    rng = np.random.default_rng(3)
    n = 400
    p = rng.uniform(-5, 8, (n, 2)) + np.array([offset, -offset])
    p[:6] = np.asarray(L_SHAPE) + [offset, -offset]  # corners: on the boundary, inside
    shape = rng.integers(-1, len(s), n)
    shape[:6] = 1
    qx, qz, inside = np.empty(n), np.empty(n), np.empty(n, bool)
    nearest(kind, start, verts, shape, p[:, 0].copy(), p[:, 1].copy(), qx, qz, inside)
    for i in range(n):
        if shape[i] < 0:
            assert (qx[i], qz[i], inside[i]) == (p[i, 0], p[i, 1], False)
            continue
        name, pts = s.shape(int(shape[i]))
        rx, rz, rin = nearest_reference(pts, name, p[i])
        assert abs(qx[i] - rx) < 1e-9 * max(1.0, offset) and abs(qz[i] - rz) < 1e-9 * max(1.0, offset)
        assert bool(inside[i]) == rin, (i, p[i])
    assert inside[:6].all()


def test_insideness_of_the_l_shape():
    s = Shapes()
    s.add("polygon", L_SHAPE)
    kind, start, verts = s.arrays()
    pts = np.array([[0.5, 0.5], [3.5, 0.5], [0.5, 2.5], [2.0, 2.0], [-0.1, 0.5], [4.0, 0.5]])
    n = len(pts)
    qx, qz, inside = np.empty(n), np.empty(n), np.empty(n, bool)
    nearest(kind, start, verts, np.zeros(n, np.int64), pts[:, 0].copy(), pts[:, 1].copy(), qx, qz, inside)
    assert inside.tolist() == [True, True, True, False, False, True]  # the notch is outside; on the edge inside


def test_crossing_follows_pedpy():
    a, b = (0.0, -1.0), (0.0, 1.0)
    assert crossed_one(-0.5, 0.0, 0.5, 0.0, *a, *b)           # through
    assert crossed_one(0.5, 0.0, -0.5, 0.3, *a, *b)           # either direction
    assert not crossed_one(-0.5, 0.0, 0.0, 0.0, *a, *b)       # ends on the line: not crossed
    assert crossed_one(0.0, 0.0, 0.5, 0.0, *a, *b)            # starts on it: crossed
    assert not crossed_one(-0.5, 2.0, 0.5, 2.0, *a, *b)       # beside the door
    assert not crossed_one(-0.5, 0.0, -0.1, 0.0, *a, *b)      # short of it
    assert crossed_one(-0.5, 1.0, 0.5, 1.0, *a, *b)           # through the jamb itself


def test_pedpy_counts_the_same_crossings():
    pedpy = pytest.importorskip("pedpy")
    import pandas as pd
    from pedpy.methods.method_utils import compute_crossing_frames

    rng = np.random.default_rng(5)
    rows, ours = [], set()
    for i in range(30):
        p = np.cumsum(rng.normal(0.0, 0.3, (20, 2)), 0) + rng.uniform(-1.5, 1.5, 2)
        p[rng.integers(0, 20), 0] = 0.0  # some moves start or end on the line
        for f in range(20):
            rows.append((i, f, p[f, 0], p[f, 1]))
        for f in range(1, 19):  # PedPy sees no move ending at a trajectory's last frame
            if crossed_one(p[f - 1, 0], p[f - 1, 1], p[f, 0], p[f, 1], 0.0, -1.0, 0.0, 1.0):
                ours.add((i, f))
    df = pd.DataFrame(rows, columns=["id", "frame", "x", "y"])
    traj = pedpy.TrajectoryData(data=df, frame_rate=10.0)
    got = compute_crossing_frames(traj_data=traj, measurement_line=pedpy.MeasurementLine([(0, -1), (0, 1)]))
    assert set(map(tuple, got[["id", "frame"]].to_numpy().tolist())) == ours
    assert len(ours) > 5


def _agents(n, s, rng, offset=0.0):
    pos = np.zeros((n, 3))
    pos[:, [0, 2]] = rng.uniform(-6, 8, (n, 2)) + [offset, -offset]
    phase = rng.choice([WALK, PENDING, HOLD, IDLE, LEAVING], n, p=[0.6, 0.1, 0.1, 0.1, 0.1]).astype(np.int8)
    tshape = rng.integers(-1, len(s), n)
    stop = np.where(rng.random(n) < 0.5, -1.0, rng.uniform(0, 2, n))
    speed = rng.uniform(0.5, 2.0, n)
    rdir = rng.normal(size=(n, 2))
    rdir /= np.hypot(rdir[:, :1], rdir[:, 1:])
    rdir[rng.random(n) < 0.2] = 0.0
    rdist = rng.uniform(0.0, 4.0, n)
    return pos, phase, tshape, stop, speed, rdir, rdist


@pytest.mark.parametrize("offset", [0.0, 1e5])
def test_desired_kernel_matches_reference(offset):
    s = _shapes(offset)
    kind, start, verts = s.arrays()
    rng = np.random.default_rng(11)
    n = 500
    pos, phase, tshape, stop, speed, rdir, rdist = _agents(n, s, rng, offset)
    out = np.empty((n, 2))
    near = (rng.random(n) < 0.3).astype(np.int8)
    near_ref = near.copy()
    desired_kernel(pos, phase, tshape, stop, speed, rdir, rdist, near, kind, start, verts, 1.5, 0.8, out)
    ref = desired_reference(pos, phase, tshape, stop, speed, rdir, rdist, near_ref, s, 1.5, 0.8)
    assert np.allclose(out, ref, atol=1e-7)
    assert np.array_equal(near, near_ref) and near.sum() > 0.3 * n
    sp = np.hypot(out[:, 0], out[:, 1])
    assert np.all(sp <= speed + 1e-12)
    assert np.all(sp[(phase > PENDING) | (tshape < 0)] == 0)


def test_desired_goes_through_a_door_from_either_side():
    s = Shapes()
    s.add("line", [[0.0, -1.0], [0.0, 1.0]])
    kind, start, verts = s.arrays()
    pos = np.array([[-0.5, 0.0, 0.2], [0.5, 0.0, -0.3], [-0.1, 0.0, 0.9]])
    out = np.empty((3, 2))
    one = np.ones(3)
    desired_kernel(pos, np.zeros(3, np.int8), np.zeros(3, np.int64), -one, one, np.zeros((3, 2)), one * 0.5,
                   np.zeros(3, np.int8), kind, start, verts, 1.0, 1.0, out)
    assert out[0, 0] > 0.5 and out[1, 0] < -0.5 and out[2, 0] > 0.5  # towards the far side, at full speed
    assert np.allclose(np.hypot(out[:, 0], out[:, 1]), 1.0)


def test_move_kernel_matches_reference():
    rng = np.random.default_rng(2)
    n = 200
    p0 = rng.normal(size=(n, 3))
    v0 = rng.normal(size=(n, 3))
    h0 = rng.uniform(-3, 3, n)
    active = rng.random(n) < 0.7
    vd = rng.normal(size=(n, 2))
    vd[::7] = 0.0
    a = [p0.copy(), v0.copy(), h0.copy()]
    b = [p0.copy(), v0.copy(), h0.copy()]
    move_kernel(*a, active, vd, 0.1)
    move_reference(*b, active, vd, 0.1)
    for x, y in zip(a, b):
        assert np.allclose(x, y, atol=1e-12)
    assert np.array_equal(a[0][~active], p0[~active])


def test_straight_router_points_at_the_nearest_point():
    r = StraightRouter()
    g = [r.goal(("point", (3.0, 4.0))), r.goal(("polygon", L_SHAPE)), r.goal(("point", (3.0, 4.0)))]
    assert g[0] == g[2]  # equal shapes share a goal
    pos = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 2.5], [0.5, 0.0, 0.5]])
    out = np.empty((3, 2))
    d = np.empty(3)
    r.directions(pos, np.array([g[0], g[1], g[1]]), out, dist=d)
    assert np.allclose(d, [5.0, 1.0, 0.0])
    assert np.allclose(out[0], [0.6, 0.8])
    assert np.allclose(out[1], [-1.0, 0.0])  # (1, 2.5) is the nearest point of the L
    assert np.allclose(out[2], 0.0)  # inside
    assert r.reachable(g[0], np.zeros((4, 2))).all()


def test_slot_layouts():
    g = grid_in_polygon(np.array([[0, 0], [3, 0], [3, 2], [0, 2]], float), 1.0)
    assert g.shape == (6, 2) and g.min() >= 0.5 - 1e-12
    d = np.hypot(g[:, None, 0] - g[None, :, 0], g[:, None, 1] - g[None, :, 1]) + np.eye(6) * 9
    assert d.min() >= 1.0 - 1e-12
    q = polyline_slots(np.array([[0, 0], [3, 0], [3, 2]], float), 1.0)
    assert np.allclose(q, [[0, 0], [1, 0], [2, 0], [3, 0], [3, 1], [3, 2]])
    assert polyline_slots(np.array([[0, 0], [3, 0]], float), 1.0, count=2).shape == (2, 2)
    rng = np.random.default_rng(0)
    s = sample_polygon(np.asarray(L_SHAPE), rng, 300)
    assert s.shape == (300, 2)
    assert not np.any((s[:, 0] > 1.0) & (s[:, 1] > 1.0))  # never in the notch
    assert math.isclose(np.mean(s[:, 1] <= 1.0), 4.0 / 6.0, abs_tol=0.08)  # uniform: the bar holds 4 of 6 m^2
