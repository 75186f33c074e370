"""The compute splat's colour rule (render/points/blend.py): its uniforms invert the projection's depth, its
tolerance is the stated number of splat footprints, and what is not a perspective projection blends nothing."""
import numpy as np

from lod.view import Camera
from render.points.blend import blend_uniforms, rule_defines


def test_the_depth_uniforms_recover_eye_depth_and_the_tolerance_is_in_footprints():
    cam = Camera.look_at((0.0, 2.0, 10.0), (0.0, 1.0, 0.0), fov_y=50.0, near=0.5, far=1000.0)
    P = cam.projection(1280 / 720)
    u = blend_uniforms(P, 720, 2, 2.0)
    a, b = u["u_depth_ab"]
    for w in (0.7, 3.0, 55.0, 800.0):  # eye depths: window depth of a point at -w on the view axis
        clip = P @ np.array([0.0, 0.0, -w, 1.0])
        d = 0.5 * clip[2] / clip[3] + 0.5
        assert abs(b / (a - (2.0 * d - 1.0)) - w) <= 1e-9 * w * 1e3
    f = 0.5 * 720 / np.tan(np.radians(25.0))  # pixels per metre at depth 1
    assert abs(u["u_tol"] - 2.0 * 2 / f) < 1e-12
    assert blend_uniforms(P, 720, 2, 0.0)["u_tol"] == 0.0


def test_no_perspective_or_non_finite_numbers_blend_only_ties():
    ortho = np.diag([0.1, 0.1, -0.01, 1.0])
    assert blend_uniforms(ortho, 720, 2, 2.0)["u_tol"] == -1.0
    bad = np.full((4, 4), np.nan)
    u = blend_uniforms(bad, 720, 2, 2.0)
    assert u["u_tol"] == -1.0 and np.isfinite(u["u_depth_ab"]).all()
    assert rule_defines(False) == ("NEAREST",) and rule_defines(True) == () and rule_defines(True, "flat") == (
        "FLAT_WEIGHT",)
