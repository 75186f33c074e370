"""View-dependent keyframes and camera extrapolation (lod.temporal.terrain_keyframes)."""
import math

import numpy as np
import pytest

from lod.full.reps import build_static_rep
from lod.temporal.terrain_keyframes import TEMPORAL_MODES, TemporalTerrainLOD, extrapolate_camera, pixel_deviation
from lod.temporal.terrain import TerrainHierarchy
from lod.view import Camera
from sim.terrain import Terrain, fbm_value_noise

SIZE = (320, 240)


@pytest.fixture(scope="module")
def hier():
    h = fbm_value_noise(65, 65, seed=4, octaves=5) * 25.0
    return TerrainHierarchy(Terrain(h, (256.0, 256.0), (-128.0, 0.0, -128.0)))


def fly(f, speed=1.5, accel=0.0):
    """A straight fly-over along -z with constant acceleration (metres per frame^2)."""
    z = 120.0 - speed * f - 0.5 * accel * f * f
    return Camera.look_at([10.0, 30.0, z], [10.0, 0.0, z - 60.0], near=0.5, far=2000.0)


def orbit(f):
    a = 0.03 * f
    return Camera.look_at([90 * math.cos(a), 35.0, 90 * math.sin(a)], [0.0, 0.0, 0.0], near=0.5, far=2000.0)


def test_selection_only_every_nth_frame(hier):
    for n in (1, 4, 8):
        for mode in TEMPORAL_MODES:
            t = TemporalTerrainLOD(hier, SIZE, n=n, tau=1.0, mode=mode)
            h0 = hier.n_selections
            frames = [t.frame(orbit(f)) for f in range(33)]
            calls = hier.n_selections - h0
            keys = math.ceil(33 / n)
            assert t.n_selections == calls
            assert calls == keys + (1 if mode == "extrapolated" else 0)
            assert [fr.selected for fr in frames] == [f % n == 0 for f in range(33)]
            assert t.n_reference_selections == 0


def test_inbetween_frames_interpolate_the_two_keyframe_sections(hier):
    n = 8
    t = TemporalTerrainLOD(hier, SIZE, n=n, tau=3.0, mode="delayed")
    frames = [t.frame(orbit(f)) for f in range(2 * n)]
    k0, k1 = t.keys[0], t.keys[1]
    frames.append(t.frame(orbit(2 * n)))
    ka, kb = frames[n], frames[2 * n]  # s = 0 of intervals (0, 1) and (1, 2): keyframes 0 and 1 exactly
    np.testing.assert_allclose(ka.grid_heights, hier.interpolated_heights(k0.selection.active))
    np.testing.assert_allclose(kb.grid_heights, hier.interpolated_heights(k1.selection.active))
    rng = np.random.default_rng(2)
    x, z = rng.uniform(-128, 128, 60), rng.uniform(-128, 128, 60)
    y = hier.positions[:, 1]
    # reference: each keyframe section's own surface (its leaves, true vertex heights)
    sa = hier.surface_height(k0.selection.leaves, y, x, z)
    sb = hier.surface_height(k1.selection.leaves, y, x, z)
    assert np.abs(sa - sb).max() > 0.05  # the two keyframes differ
    for r in (1, 3, 5, 7):
        fr = frames[n + r]
        assert fr.s == pytest.approx(r / n) and not fr.selected
        got = hier.surface_height(hier.section(_active_of(fr, hier)).leaves, fr.grid_heights, x, z)
        np.testing.assert_allclose(got, (1 - r / n) * sa + (r / n) * sb, atol=1e-9)
        assert set(np.unique(fr.flags)) <= {1, 2, 3} and (fr.flags == 3).any()
        assert (fr.flags != 3).any()


def _active_of(frame, hier):
    """Active vertices of a drawn union section: every vertex it uses but the four corners was inserted."""
    act = np.zeros(hier.n_vertices, bool)
    act[frame.triangles.ravel()] = True
    corners = [0, hier.n_side - 1, hier.n_vertices - 1, hier.n_vertices - hier.n_side]
    act[corners] = False
    return act


def test_keyframe_surface_is_exact_and_union_conforming(hier):
    t = TemporalTerrainLOD(hier, SIZE, n=4, tau=1.0, mode="delayed")
    for f in range(9):
        fr = t.frame(orbit(f))
    key = t.keys[2]
    exact = hier.interpolated_heights(key.selection.active)
    # frame 8 (s = 0 of interval (1, 2)) draws keyframe 1 exactly; check the union mesh is conforming
    used = np.zeros(hier.n_vertices, bool)
    used[fr.triangles.ravel()] = True
    n = hier.n_side
    for tri in fr.triangles[:400]:
        a, b = tri[0], tri[1]
        if (a % n + b % n) % 2 == 0 and (a // n + b // n) % 2 == 0:
            assert not used[((a // n + b // n) // 2) * n + (a % n + b % n) // 2]
    np.testing.assert_allclose(fr.grid_heights, t.keys[1].heights)
    assert exact.shape == (hier.n_vertices,)
    m = fr.mesh()
    assert np.isfinite(m.positions).all() and m.indices.max() < m.n_vertices
    assert build_static_rep(m, "terrain").indices.shape[0] == fr.triangles.shape[0]


def test_no_popping_flicker_bounded_by_interpolation_step(hier):
    n = 8
    F = 49
    t = TemporalTerrainLOD(hier, SIZE, n=n, tau=3.0, mode="delayed")
    per = TemporalTerrainLOD(hier, SIZE, n=1, tau=3.0, mode="delayed")
    fk = [t.frame(orbit(f)) for f in range(F)]
    fp = [per.frame(orbit(f)) for f in range(F)]
    key_jump = max(np.abs(fk[i + n].grid_heights - fk[i].grid_heights).max() for i in range(n, F - n, n))
    step_k = [np.abs(b.grid_heights - a.grid_heights).max() for a, b in zip(fk, fk[1:])]
    # in world space, the drawn surface moves at most one interpolation step per frame,
    # across keyframe switches included
    assert max(step_k) <= key_jump / n + 1e-9
    assert max(step_k) > 0
    # screen-space flicker (seen with the later frame's camera) is far below per-frame selection's
    flick_k = [pixel_deviation(hier, b.grid_heights, a.grid_heights, b.camera, SIZE) for a, b in zip(fk, fk[1:])]
    flick_p = [pixel_deviation(hier, b.grid_heights, a.grid_heights, b.camera, SIZE) for a, b in zip(fp, fp[1:])]
    assert np.mean(flick_p) > 1.0
    assert np.mean(flick_k[n:]) < 0.35 * np.mean(flick_p[n:])


def test_error_terms_zero_for_static_camera(hier):
    cam = orbit(3)
    for mode in TEMPORAL_MODES:
        t = TemporalTerrainLOD(hier, SIZE, n=4, tau=1.0, mode=mode, measure_errors=True)
        for f in range(13):
            fr = t.frame(cam)
            assert fr.err_inter == 0.0 and fr.err_view == 0.0 and fr.err_extra == 0.0
        assert t.n_reference_selections > 0


def test_error_terms_for_moving_camera(hier):
    n = 8
    res = {}
    for mode in TEMPORAL_MODES:
        t = TemporalTerrainLOD(hier, SIZE, n=n, tau=1.0, mode=mode, measure_errors=True)
        fr = [t.frame(fly(f, speed=2.0)) for f in range(33)]
        res[mode] = fr
    d = res["delayed"]
    assert max(f.delay for f in d) == pytest.approx(n / 30.0)
    assert all(f.err_view == 0.0 and f.err_extra == 0.0 for f in d)
    c = res["current"]
    assert max(f.err_view for f in c) > 0.0  # the current matrix shows a stale section
    assert all(f.delay == 0.0 for f in res["extrapolated"])
    # constant velocity: the linear extrapolation is exact, no extrapolation error
    # (the first extrapolation, at frame 0, has no velocity yet: skip its interval)
    assert max(f.err_extra for f in res["extrapolated"][2 * n:]) == pytest.approx(0.0, abs=1e-9)
    assert max(f.err_extra for f in res["extrapolated"][n:2 * n]) > 0.0


def test_extrapolation_error_grows_with_acceleration(hier):
    errs = []
    for acc in (0.0, 0.05, 0.2):
        t = TemporalTerrainLOD(hier, SIZE, n=8, tau=0.7, mode="extrapolated", measure_errors=True)
        fr = [t.frame(fly(f, speed=1.0, accel=acc)) for f in range(41)]
        errs.append(np.mean([f.err_extra for f in fr[16:]]))
    assert errs[0] == pytest.approx(0.0, abs=1e-9)
    assert errs[0] < errs[1] < errs[2], errs


def test_extrapolate_camera_and_bad_parameters(hier):
    a, b = fly(0, 1.0), fly(1, 1.0)
    c = extrapolate_camera(a, b, 8)
    np.testing.assert_allclose(c.position, fly(9, 1.0).position, atol=1e-9)
    np.testing.assert_allclose(c.forward, b.forward, atol=1e-9)
    o = extrapolate_camera(orbit(0), orbit(1), 4)
    assert np.isfinite(o.rotation).all()
    with pytest.raises(ValueError, match="mode"):
        TemporalTerrainLOD(hier, SIZE, mode="predictive")
    with pytest.raises(ValueError, match="n"):
        TemporalTerrainLOD(hier, SIZE, n=0)
    with pytest.raises(ValueError, match="dt"):
        TemporalTerrainLOD(hier, SIZE, dt=0.0)
    # a camera looking away from the terrain: nothing in view, errors 0, still a valid mesh
    away = Camera.look_at([0.0, 50.0, 0.0], [0.0, 100.0, 0.0], near=0.5)
    t = TemporalTerrainLOD(hier, SIZE, n=2, measure_errors=True)
    fr = [t.frame(away) for _ in range(3)]
    assert fr[-1].error == 0.0 and fr[-1].triangles.shape[0] >= 2


def test_terrain_lod_from_params(hier):
    from lod.temporal.terrain_keyframes import TERRAIN_LOD_PARAMS, terrain_lod_from_params

    assert terrain_lod_from_params(hier.terrain, SIZE, {}, 1 / 30) is None
    t = terrain_lod_from_params(hier.terrain, SIZE, {"lod": "bisection", "lod_keyframe_every": 4,
                                                     "lod_extrapolation": "current", "size": [1, 1]}, 1 / 30)
    assert t.n == 4 and t.mode == "current"
    fr = t.frame(orbit(0))
    assert fr.mesh().n_triangles == fr.triangles.shape[0]
    assert TERRAIN_LOD_PARAMS["lod_extrapolation"].check("x", "delayed") == "delayed"
