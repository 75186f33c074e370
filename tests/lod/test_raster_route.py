"""lod/raster_route.py: which copies go to the compute rasteriser."""
import numpy as np

from lod.raster_route import compute_mask, near_distance, triangle_extent
from lod.view import Camera


def test_near_distance_of_a_perspective_projection():
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y=50.0, near=0.25, far=300.0)
    assert abs(near_distance(cam.projection(16 / 9)) - 0.25) < 1e-9
    assert near_distance(np.eye(4)) == 0.0


def test_triangle_extent_ignores_non_finite_vertices():
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [np.nan, 0, 0]], float)
    ext, radius, centre = triangle_extent(pos, [[0, 1, 2]], percentile=50.0)
    assert ext == 2.0 and np.allclose(centre, [0.5, 1.0, 0.0]) and abs(radius - np.sqrt(1.25)) < 1e-12


def test_compute_mask_follows_distance_scale_and_the_near_plane():
    """A 0.1 m triangle extent at 720 px, fov 50: compute beyond ~ 0.1 * 772 / 8 = 9.7 m (threshold 8 px);
    a copy scaled x4 needs 4x the distance; a copy whose sphere reaches the near plane never goes."""
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y=50.0, near=0.1, far=1000.0)
    proj = cam.projection(16 / 9)
    rows = np.zeros((6, 16))
    rows[:, [0, 5, 10]] = 1.0
    rows[:, 11] = [-5.0, -15.0, -30.0, -30.0, -0.2, -60.0]
    rows[3, [0, 5, 10]] = 4.0
    rows[5, 3] = np.inf  # non-finite: never
    m = compute_mask(rows, 0.1, 0.5, np.zeros(3), proj, 720, 8.0, 0.1)
    assert m.tolist() == [False, True, True, False, False, False]
