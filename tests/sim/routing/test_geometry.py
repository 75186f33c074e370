"""sim.routing.geometry: the walkable area, its checks, walls and raster."""
import math

import numpy as np
import pytest
import shapely

from sim.routing.geometry import (
    Walkable,
    circle_polygon,
    polygon_problem,
    raster,
    raster_numpy,
    shape_problem,
    wall_polygons,
)

ROOM = {"walkable": [{"points": [[0.0, 0.0], [10.0, 0.0], [10.0, 6.0], [0.0, 6.0]],
                      "holes": [[[2.0, 2.0], [3.0, 2.0], [3.0, 3.0], [2.0, 3.0]]]}]}
OBS = {"circles": [{"center": [7.0, 3.0], "radius": 0.8}], "boxes": [{"center": [5.0, 1.0], "size": [1.0, 0.4],
                                                                     "yaw": 30.0}], "polygons": []}


def test_circle_polygon_circumscribes():
    p = circle_polygon(1.0, -2.0, 0.5, 16)
    d = np.hypot(p[:, 0] - 1.0, p[:, 1] + 2.0)
    mid = (p + np.roll(p, -1, 0)) / 2
    assert np.all(d >= 0.5) and np.allclose(np.hypot(mid[:, 0] - 1.0, mid[:, 1] + 2.0), 0.5)


def test_polygon_problems_name_the_fault():
    assert polygon_problem([[0, 0], [1, 0], [1, 1]]) is None
    assert "intersects itself near (1, 1)" in polygon_problem([[0, 0], [2, 2], [2, 0], [0, 2]])  # a bow tie
    assert "hole outside" in polygon_problem([[0, 0], [1, 0], [1, 1], [0, 1]], [[[5, 5], [6, 5], [6, 6]]])
    assert polygon_problem([[0, 0], [1, 0], [2, 0]]) == "has zero area"
    assert "fewer than 3" in polygon_problem([[0, 0], [1, 0]])


def test_walkable_where_and_shapes():
    w = Walkable.from_config(ROOM, OBS)
    assert w.area.area == pytest.approx(60 - 1 - 0.4 - math.pi * 0.64, rel=2e-3)  # room - hole - box - circle
    code = w.where([(1, 1), (-1, 1), (2.5, 2.5), (7.0, 3.0), (10.0, 3.0)])
    assert code.tolist() == [0, 1, 1, 2, 0]  # inside, outside, in a hole (outside), in an obstacle, on the edge
    assert shape_problem(w, ("point", (1, 1))) is None
    assert shape_problem(w, ("point", (7.0, 3.2))) == "lies inside an obstacle"
    assert shape_problem(w, ("point", (12, 3))) == "lies outside the walkable area"
    assert "zero width" in shape_problem(w, ("line", ((4, 4), (4, 4))))
    assert shape_problem(w, ("line", ((9, -1), (9, 7)))) is None  # crosses the area
    assert shape_problem(w, ("line", ((11, -1), (11, 7)))) == "lies outside the walkable area"
    assert "intersects itself" in shape_problem(w, ("polygon", [(0, 0), (2, 2), (2, 0), (0, 2)]))
    assert shape_problem(w, ("polygon", [(6.9, 2.9), (7.1, 2.9), (7.1, 3.1)])) == "lies inside an obstacle"
    assert "unknown shape" in shape_problem(w, ("blob", None))


def test_walls_are_simple_and_close_the_area():
    w = Walkable.from_config(ROOM, None)
    walls = wall_polygons(w, 0.5)
    polys = [shapely.Polygon(p) for p in walls]
    assert all(p.is_valid and not p.interiors for p in polys)
    u = shapely.union_all(polys)
    assert u.intersection(w.outer).area < 1e-9  # walls never cover the area
    assert u.union(w.outer).area == pytest.approx(11.0 * 7.0)  # and fill the frame with it
    assert u.contains(shapely.Point(2.5, 2.5))  # the hole is a wall


@pytest.mark.parametrize("origin", [(0.0, 0.0), (1.0e6, -2.0e6)])
def test_raster_equals_shapely(origin):
    ox, oz = origin
    room = {"walkable": [{"points": [[ox + x, oz + z] for x, z in t] , "holes": [[[ox + x, oz + z] for x, z in h]
                                                                          for h in r["holes"]]}
                         for r in ROOM["walkable"] for t in [r["points"]]]}
    obs = {"circles": [{"center": [ox + 7.0, oz + 3.0], "radius": 0.8}], "boxes": [], "polygons": []}
    w = Walkable.from_config(room, obs)
    h = 0.13
    x0, z0 = ox - 0.51, oz - 0.37
    nx, nz = int(11.0 / h), int(7.0 / h)
    inside, wall = raster(w, x0, z0, h, nx, nz, 0.6)
    ref_in, ref_wall = raster_numpy(w, x0, z0, h, nx, nz, 0.6)
    X, Z = np.meshgrid(x0 + np.arange(nx) * h, z0 + np.arange(nz) * h)
    on_edge = shapely.distance(w.area.boundary, shapely.points(X.ravel(), Z.ravel())).reshape(nz, nx) < 1e-6
    assert np.array_equal(inside[~on_edge], ref_in[~on_edge])
    near = np.isfinite(ref_wall) & (ref_wall < 0.55)
    assert np.array_equal(np.isfinite(wall) & (wall < 0.55), near)
    np.testing.assert_allclose(wall[near], ref_wall[near], atol=1e-6 * (1 + abs(ox) * 1e-6))
