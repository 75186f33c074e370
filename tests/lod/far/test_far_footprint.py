"""The far footprint (lod.far.footprint): covered area and mean colours of known shapes by view."""
import numpy as np
import pytest

from lod.far import footprint as fp
from lod.far.rep import build_far_rep, clip_surfaces


def _cube(colors_by_face=None):
    """A unit cube (centred at the origin) as 12 triangles with flat normals: (P, N, C, idx)."""
    P, N, C, idx = [], [], [], []
    faces = [((1, 0, 0), (0, 0, -1), (0, 1, 0)), ((-1, 0, 0), (0, 0, 1), (0, 1, 0)),
             ((0, 1, 0), (1, 0, 0), (0, 0, -1)), ((0, -1, 0), (1, 0, 0), (0, 0, 1)),
             ((0, 0, 1), (1, 0, 0), (0, 1, 0)), ((0, 0, -1), (-1, 0, 0), (0, 1, 0))]
    for f, (n, u, v) in enumerate(faces):
        n, u, v = (np.array(a, float) for a in (n, u, v))
        base = len(P)
        for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            P.append(0.5 * n + 0.5 * su * u + 0.5 * sv * v)
            N.append(n)
            C.append((colors_by_face or {}).get(f, (1.0, 1.0, 1.0)) + (1.0,))
        idx += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return np.array(P), np.array(N), np.array(C), np.array(idx)


def _sphere(n=48):
    """A unit sphere (UV mesh) with its true normals, white."""
    th = np.linspace(0, np.pi, n + 1)
    ph = np.linspace(0, 2 * np.pi, 2 * n + 1)
    T, F = np.meshgrid(th, ph, indexing="ij")
    P = np.stack([np.sin(T) * np.cos(F), np.cos(T), np.sin(T) * np.sin(F)], -1).reshape(-1, 3)
    W = 2 * n + 1
    idx = []
    for i in range(n):
        for j in range(2 * n):
            a, b, c, d = i * W + j, i * W + j + 1, (i + 1) * W + j, (i + 1) * W + j + 1
            idx += [(a, c, b), (b, c, d)]
    return P, P.copy(), np.ones((P.shape[0], 4)), np.array(idx)


def test_grid_directions_are_unit_and_start_at_the_front():
    d = fp.grid_directions(16, 9)
    assert d.shape == (9, 16, 3)
    assert np.allclose(np.linalg.norm(d, axis=-1), 1.0)
    assert np.allclose(d[4, 0], (0, 0, 1)) and np.allclose(d[4, 4], (1, 0, 0))  # front, then towards +X
    assert np.allclose(d[8, :], (0, 1, 0), atol=1e-12) and np.allclose(d[0, :], (0, -1, 0), atol=1e-12)


def test_cube_area_is_its_projected_area_from_every_view():
    t = fp.measure([_cube()])
    d = fp.grid_directions(fp.VIEW_AZIMUTHS, fp.VIEW_ELEVATIONS)
    want = np.abs(d).sum(axis=-1)  # a unit cube seen along d covers |dx| + |dy| + |dz|
    # pixel centres quantise an axis-aligned edge by up to half a pixel each side: 1/36 of the side at 64 pixels
    assert np.allclose(t.area, want, rtol=0.03), np.abs(t.area / want - 1).max()
    assert t.radius == pytest.approx(np.sqrt(3) / 2)


def test_nearest_face_wins_and_colours_are_means_over_covered_area():
    red = {4: (1.0, 0.0, 0.0)}  # the +Z face red, the rest white
    t = fp.measure([_cube(red)])
    assert np.allclose(t.ambient[4, 0], (1, 0, 0), atol=1e-9)  # front view: only the red face
    assert np.allclose(t.head[4, 0], (1, 0, 0), atol=1e-9)  # |n . d| = 1 there
    assert np.allclose(t.ambient[4, 8], (1, 1, 1), atol=1e-9)  # from behind: white
    # from az 45 degrees the red face and the +X face show equal areas: a half-red mean
    assert np.allclose(t.ambient[4, 2], (1, 0.5, 0.5), atol=0.02)


def test_sphere_headlight_and_light_means():
    t = fp.measure([_sphere()])
    assert np.allclose(t.area, np.pi, rtol=0.02)
    # seen orthographically, the mean of n . d over the disc is the mean of sqrt(1 - r^2): 2/3
    assert np.allclose(t.head, 2.0 / 3.0, atol=0.01)
    # a light along the view: the same; a light at right angles: mean |n . l| over the half seen = 4 / (3 pi)
    lit_same = t.direct[4, 0, 4, 0]
    lit_side = t.direct[4, 0, 4, 4]
    assert np.allclose(lit_same, 2.0 / 3.0, atol=0.01)
    assert np.allclose(lit_side, 4.0 / (3.0 * np.pi), atol=0.01)


def test_lit_follows_the_renderer_shading_at_a_grid_light():
    t = fp.measure([_cube({4: (0.2, 0.6, 0.9)})])
    l_dirs = fp.grid_directions(fp.LIGHT_AZIMUTHS, fp.LIGHT_ELEVATIONS)
    got = t.lit(l_dirs[6, 3], light_color=(1.0, 0.5, 0.25), ambient=0.2)
    want = 0.2 * t.ambient + 0.35 * t.head + 0.55 * np.array([1.0, 0.5, 0.25]) * t.direct[:, :, 6, 3]
    assert np.allclose(got, want, atol=1e-12)
    # between two grid lights of one elevation (azimuth halfway): between their colours
    el = np.radians(-90 + 180 * 6 / (fp.LIGHT_ELEVATIONS - 1))
    az = 2 * np.pi * 3.5 / fp.LIGHT_AZIMUTHS
    mid = t.lit([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
    a, b = t.lit(l_dirs[6, 3]), t.lit(l_dirs[6, 4])
    assert np.all(mid >= np.minimum(a, b) - 1e-9) and np.all(mid <= np.maximum(a, b) + 1e-9)


def test_poses_average_area_and_weight_colours_by_area():
    small = _cube({k: (0.0, 0.0, 0.0) for k in range(6)})
    big = _cube()
    big = (big[0] * 2.0, big[1], big[2], big[3])
    t = fp.measure([small, big])
    assert t.area[4, 0] == pytest.approx((1.0 + 4.0) / 2, rel=0.03)  # pixel quantisation as above
    assert t.ambient[4, 0][0] == pytest.approx(4.0 / 5.0, abs=0.02)  # white over 4 of the 5 m^2


def test_degenerate_and_non_finite_poses():
    P, N, C, idx = _cube()
    flat = P.copy()
    flat[:, 2] = 0.0  # squashed to a square: seen edge-on covers nothing, from the front one m^2
    t = fp.measure([(flat, N, C, idx)])
    assert t.area[4, 0] == pytest.approx(1.0, rel=0.03) and t.area[4, 4] < 0.05
    bad = P.copy()
    bad[0] = np.nan
    t2 = fp.measure([(bad, N, C, idx)])
    assert t2.radius == 0.0 and not t2.area.any()
    assert np.isfinite(t2.lit([0, 1, 0])).all()
    empty = fp.measure([])
    assert not empty.area.any() and np.isfinite(empty.ambient).all()
    with pytest.raises(ValueError, match="indices"):
        fp.measure([(P[:3], N[:3], C[:3], idx)])


def test_far_rep_of_a_skinned_humanoid():
    from lod.full.reps import build_skinned_rep
    from sim.procedural import humanoid

    rep = build_skinned_rep(humanoid(800, 3))
    surf = clip_surfaces(rep, 0, 4)
    assert len(surf) == 4 and all(np.isfinite(s[0]).all() and np.isfinite(s[1]).all() for s in surf)
    far = build_far_rep(rep, "h", clips=[0])
    assert far.key == "far:h" and far.kind == "far" and far.n_clips == len(rep.clip_names)
    t = far.tables[0]
    height = float(rep.clip_aabb[0, 1, 1] - rep.clip_aabb[0, 0, 1])
    # a standing humanoid: seen from the front it covers more than from above, a fraction of height^2
    assert t.area[4, 0] > t.area[8, 0] > 0 and 0.05 < t.area[4, 0] / height ** 2 < 0.5
    assert 0 < far.radius()[0] <= float(rep.clip_sphere[0, 3]) + 1e-6
    assert not far.tables[1].area.any()  # a clip the scene does not play: empty


def test_cache_reads_back_and_rebuilds_a_corrupt_entry(tmp_path, monkeypatch):
    from lod.far import cache

    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path))
    surf = [_cube({4: (0.2, 0.6, 0.9)})]
    first = cache.measured(surf)
    files = list((tmp_path / "far").glob("*.npz"))
    assert len(files) == 1 and files[0].stem == cache.key(surf)
    calls, real = [], fp.measure
    monkeypatch.setattr(cache.fp, "measure", lambda s, **kw: calls.append(1) or real(s, **kw))
    again = cache.measured(surf)
    assert not calls  # read back, not measured
    for f in ("area", "ambient", "head", "direct", "centre"):
        assert np.array_equal(getattr(again, f), getattr(first, f))
    assert again.radius == first.radius
    for bad in (b"not a zip", b""):
        files[0].write_bytes(bad)
        rebuilt = cache.measured(surf)
        assert calls and np.array_equal(rebuilt.area, first.area)
        assert cache.load(files[0]) is not None  # replaced by a good entry
    other = [_cube({4: (0.9, 0.6, 0.2)})]
    assert cache.key(other) != cache.key(surf)


def test_ground_rings_are_hidden_where_the_body_stands():
    """A pole 0.2 m wide and 2 m tall on the floor: from above it hides only the floor under it (the innermost
    ring); seen from the side at 22.5 degrees it hides the part of each ring behind it, asin(0.1 / r) / pi."""
    P, N, C, idx = _cube()
    pole = P * np.array([0.2, 2.0, 0.2]) + np.array([0.0, 1.0, 0.0])  # floor at y = 0
    t = fp.measure([(pole, N, C, idx)], rest=pole)
    r = t.ring_radii()
    assert np.allclose(t.floor, (0.0, 0.0, 0.0)) and np.allclose(t.extent, (0.2, 2.0, 0.2))
    assert np.allclose(r, (np.arange(fp.RINGS) + 0.5) / fp.RINGS * fp.RING_EXTENT * 2.0)
    top = t.ground[-1, 0]
    assert top[0] == 0.0 and np.all(top[r > 0.1 * np.sqrt(2) + 0.03] == 1.0)
    side = t.ground[5, 0]  # elevation 22.5 degrees, from the front
    want = 1.0 - np.arcsin(np.minimum(0.1 / r, 1.0)) / np.pi
    assert np.allclose(side[r > 0.2], want[r > 0.2], atol=0.05), (side, want)
    # a table without a rest pose places the rings by the first pose; an empty one sees every ring
    assert np.allclose(fp.measure([(pole, N, C, idx)]).ground, t.ground)
    assert np.all(fp.measure([]).ground == 1.0)
