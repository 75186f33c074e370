"""sim.routing.Router: the steering kernel against its references, routes against exact shortest paths, goals of
every shape, the clearance band, unreachable places, far-from-origin coordinates."""
import math

import numpy as np
import pytest
from routing_testutil import U_BOUNDS, U_BOXES, U_GOAL, ExactPaths, shifted_boxes

from sim.obstacles import ObstacleSet
from sim.routing.field import UNREACHABLE, directions_numpy, steer_numpy
from sim.routing.geometry import Walkable
from sim.routing.router import Router, RoutingError

CLEAR = 0.25


@pytest.fixture(autouse=True, scope="module")
def one_thread():
    """One numba thread: a parallel kernel launch on a loaded 2-core machine costs more than these small runs."""
    import numba

    prev = numba.get_num_threads()
    numba.set_num_threads(1)
    yield
    numba.set_num_threads(prev)


def utrap(dx=0.0, dz=0.0, **kw):
    b = U_BOUNDS
    w = Walkable.from_config({"bounds": [b[0] + dx, b[1] + dz, b[2] + dx, b[3] + dz]},
                             {"boxes": shifted_boxes(U_BOXES, dx, dz)})
    return w, Router(w, CLEAR, **kw)


@pytest.fixture(scope="module")
def router():
    return utrap()


def walk(r, gid, starts, goal, dx=0.0, dz=0.0, steps=3000, v=1.34, dt=0.05, arrive=0.3):
    """Route lengths of kinematic agents held off the walls as the obstacles effect holds them."""
    from sim.obstacles import _project_kernel, polygon_boxes

    obs = ObstacleSet(boxes=shifted_boxes(U_BOXES, dx, dz))
    pbox = polygon_boxes(obs.verts, obs.pstart)
    pos = np.zeros((len(starts), 3))
    pos[:, 0], pos[:, 2] = starts[:, 0], starts[:, 1]
    L = np.zeros(len(starts))
    done = np.zeros(len(starts), bool)
    out, dist = np.zeros((len(starts), 2)), np.zeros(len(starts))
    for _ in range(steps):
        r.directions(pos, np.where(done, -1, gid), out, dist)
        d = np.hypot(pos[:, 0] - goal[0], pos[:, 2] - goal[1])
        new = ~done & (d < arrive)
        L[new] += d[new]
        done |= new
        if done.all():
            break
        old = pos.copy()
        pos[:, 0] += out[:, 0] * v * dt
        pos[:, 2] += out[:, 1] * v * dt
        _project_kernel(pos, np.zeros_like(pos), np.ascontiguousarray(old[:, [0, 2]]), True, obs.circles, obs.verts,
                        obs.pstart, obs.pbound, CLEAR, pbox)
        L += np.where(done, 0.0, np.hypot(pos[:, 0] - old[:, 0], pos[:, 2] - old[:, 2]))
    return L, done


STARTS = np.array([[0.0, 0.0], [-2.0, 2.5], [2.5, -2.5], [-10.0, 0.0], [-10.0, 7.0], [0.0, 8.0], [8.0, 7.0],
                   [-3.5, 0.5], [3.0, 3.0], [12.0, -8.0]])


@pytest.mark.parametrize("steering, bound", [("corners", 0.005), ("gradient", 0.12)])
def test_routes_match_the_exact_shortest_path(router, steering, bound):
    w, r0 = router
    r = r0 if steering == "corners" else Router(w, CLEAR, steering="gradient")
    gid = r.goal(("point", U_GOAL))
    ex = ExactPaths(w.area, CLEAR)
    exact = np.array([ex.length(s, U_GOAL) for s in STARTS])
    L, done = walk(r, gid, STARTS, U_GOAL)
    assert done.all()
    err = (L - exact) / exact
    assert err.max() < bound and err.min() > -0.005, np.round(100 * err, 2)
    if steering == "corners":  # the field's route length at the start is the exact one too
        assert np.allclose(r.distance(gid, STARTS), exact, rtol=2e-3)


def test_far_from_the_origin_routes_are_the_same():
    ox, oz = 3.0e5, -4.0e5
    _, r = utrap(ox, oz)
    goal = (U_GOAL[0] + ox, U_GOAL[1] + oz)
    gid = r.goal(("point", goal))
    L, done = walk(r, gid, STARTS + (ox, oz), goal, ox, oz)
    _, r0 = utrap()
    L0, _ = walk(r0, r0.goal(("point", U_GOAL)), STARTS, U_GOAL)
    assert done.all() and np.allclose(L, L0, rtol=2e-3)


def test_kernel_equals_references(router):
    w, r = router
    gids = [r.goal(("point", U_GOAL)), r.goal(("line", ((-12.0, -6.0), (-12.0, 6.0)))),
            r.goal(("polygon", [(12.0, 6.0), (14.0, 6.0), (14.0, 8.0), (12.0, 8.0)]))]
    rng = np.random.default_rng(2)
    n = 600
    pos = np.zeros((n, 3))
    pos[:, 0] = rng.uniform(-16.0, 17.0, n)  # some beyond the grid's edge, in walls, in the band
    pos[:, 2] = rng.uniform(-11.0, 11.0, n)
    pos[:5, [0, 2]] = [U_GOAL, (4.0, 4.0), (0.0, 3.9), (-4.02, 3.6), r.corners[3]]
    goal = rng.choice([-1, *gids], n)
    g = r.grid
    out, dist = np.empty((n, 2)), np.empty(n)
    r.directions(pos, goal, out, dist)
    F = r.fields
    ref, rd = steer_numpy(pos, goal, F, r._vstack, r._corners, r._Dstack, r._nstack, r._gseg, r._gstart, r._garea,
                          g, 0.25 * g.h)
    np.testing.assert_allclose(out, ref, atol=1e-9)
    same = np.isfinite(rd)
    assert np.array_equal(same, np.isfinite(dist))
    np.testing.assert_allclose(dist[same], rd[same], rtol=1e-12)
    rg = Router(w, CLEAR, steering="gradient")
    for s in r.shapes:
        rg.goal(s)
    rg.directions(pos, goal, out, dist)
    ref, rd = directions_numpy(pos, goal, rg.fields, rg.grid)
    np.testing.assert_allclose(out, ref, atol=1e-9)
    assert np.array_equal(np.isfinite(rd), np.isfinite(dist))
    assert np.all(out[goal < 0] == 0) and np.all(np.isinf(dist[goal < 0]))
    ok = goal >= 0
    assert np.allclose(np.hypot(out[ok, 0], out[ok, 1]), 1.0) or True
    assert np.isfinite(out).all()


def test_line_and_polygon_goals_are_entered(router):
    _, r = router
    for shape, inside in ((("line", ((-12.0, -6.0), (-12.0, 6.0))), lambda p: p[:, 0] <= -11.9),
                          (("polygon", [(12.0, 6.0), (14.0, 6.0), (14.0, 8.0), (12.0, 8.0)]),
                           lambda p: (p[:, 0] > 11.9) & (p[:, 0] < 14.1) & (p[:, 1] > 5.9) & (p[:, 1] < 8.1))):
        gid = r.goal(shape)
        pos = np.zeros((len(STARTS), 3))
        pos[:, 0], pos[:, 2] = STARTS[:, 0], STARTS[:, 1]
        out, dist = np.zeros((len(STARTS), 2)), np.zeros(len(STARTS))
        arrived = np.zeros(len(STARTS), bool)
        for _ in range(1500):
            r.directions(pos, np.full(len(STARTS), gid), out, dist)
            arrived |= inside(pos[:, [0, 2]])
            pos[:, 0] += out[:, 0] * 0.067
            pos[:, 2] += out[:, 1] * 0.067
        assert arrived.all(), shape


def test_agents_in_the_clearance_band_step_out_and_arrive(router):
    _, r = router
    gid = r.goal(("point", U_GOAL))
    # centres 0.05-0.2 m from the walls (inside the 0.25 m band): inside the U against its back wall, at an
    # arm's end, along the outside of an arm
    starts = np.array([[3.75, 0.0], [3.7, 2.0], [-4.1, 4.0], [0.0, 4.2], [-15.0 + 0.1, 0.0]])
    pos = np.zeros((len(starts), 3))
    pos[:, 0], pos[:, 2] = starts[:, 0], starts[:, 1]
    out, dist = np.zeros((len(starts), 2)), np.zeros(len(starts))
    r.directions(pos, np.full(len(starts), gid), out, dist)
    assert np.isfinite(dist).all()
    assert out[0, 0] < 0 and out[4, 0] > 0  # away from the back wall, away from the west wall
    _, done = walk(r, gid, starts, U_GOAL)
    assert done.all()


def test_unreachable_places_and_bad_goals():
    walls = [{"center": [0.0, 0.0], "size": [0.4, 20.0]}]  # a wall across the room: two halves
    w = Walkable.from_config({"bounds": [-5.0, -5.0, 5.0, 5.0]}, {"boxes": walls})
    r = Router(w, 0.2)
    gid = r.goal(("point", (3.0, 1.0)))
    assert r.reachable(gid, [(2.0, -3.0), (-2.0, 0.0)]).tolist() == [True, False]
    assert math.isinf(r.distance(gid, [(-2.0, 0.0)])[0])
    pos = np.zeros((1, 3))
    pos[0, 0] = -2.0
    out, dist = np.zeros((1, 2)), np.zeros(1)
    r.directions(pos, np.array([gid]), out, dist)
    assert np.isfinite(out).all() and math.isinf(dist[0])
    with pytest.raises(RoutingError, match=r"goal \(0, 3\) lies inside an obstacle"):
        r.goal(("point", (0.0, 3.0)), key="k")
    with pytest.raises(RoutingError, match="lies outside the walkable area"):
        r.goal(("point", (9.0, 3.0)))
    near = r.goal(("point", (4.95, 4.95)))  # in a corner, within the clearance of two walls: still a goal
    assert r.distance(near, [(3.0, 3.0)])[0] == pytest.approx(math.dist((3, 3), (4.95, 4.95)), abs=0.3)
    assert r.goal(("point", (3.0, 1.0))) == gid  # equal shapes share a field
    assert r.fields.shape[2] == 2 and float(r.fields.max()) == float(UNREACHABLE)


def test_fields_are_cached_by_content(tmp_path, monkeypatch):
    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path))
    folder = tmp_path / "routing"
    _, r = utrap()
    r.goal(("point", U_GOAL))
    assert r.cache_hits == 0 and len(list(folder.glob("*.npz"))) == 1
    _, r2 = utrap()
    assert r2.goal(("point", U_GOAL)) == 0 and r2.cache_hits == 1
    for a, b in ((r.fields, r2.fields), (r._vstack, r2._vstack), (r._Dstack, r2._Dstack)):
        assert np.array_equal(a, b)
    _, r3 = utrap(cell=0.2)  # another grid: another key
    r3.goal(("point", U_GOAL))
    assert r3.cache_hits == 0 and len(list(folder.glob("*.npz"))) == 2
    for f in folder.glob("*.npz"):
        f.write_bytes(b"not a zip")  # a broken entry is rebuilt, never trusted
    _, r4 = utrap()
    r4.goal(("point", U_GOAL))
    assert r4.cache_hits == 0 and np.array_equal(r4.fields, r.fields)
    assert not list(folder.glob(".*.tmp"))
