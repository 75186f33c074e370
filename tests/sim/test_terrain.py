"""sim.terrain and the terrain_follow effect."""
import numpy as np
import pytest

from sim.errors import AssetError
from sim.params import ParamError, validate
from sim.state import CrowdState
from sim.terrain import PARAMS, Terrain, fbm_value_noise, load_heights
from sim.world import World


def small():
    h = np.array([[0.0, 1.0, 3.0], [2.0, 5.0, 4.0]])  # nz = 2, nx = 3
    return Terrain(h, size=(10.0, 4.0), origin=(-5.0, 1.0, 2.0))


def test_bilinear_exact_at_nodes_and_between():
    t = small()
    x = -5.0 + np.array([0, 1, 2, 0, 1, 2]) * 5.0
    z = 2.0 + np.array([0, 0, 0, 1, 1, 1]) * 4.0
    np.testing.assert_allclose(t.height(x, z), 1.0 + t.heights.ravel())
    assert t.height(-2.5, 4.0) == pytest.approx(1.0 + (0 + 1 + 2 + 5) / 4)
    # clamped outside
    assert t.height(-100.0, -100.0) == pytest.approx(1.0)
    assert t.height(100.0, 100.0) == pytest.approx(5.0)


def test_normals_unit_and_match_slope():
    t = Terrain(np.add.outer(np.zeros(5), np.arange(5) * 2.0), size=(4.0, 4.0), origin=(0, 0, 0))  # h = 2x
    n = t.normal(np.array([0.5, 2.2, -10.0]), np.array([1.0, 3.9, 50.0]))
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0)
    np.testing.assert_allclose(n[0], np.array([-2.0, 1.0, 0.0]) / np.sqrt(5.0))
    rng = np.random.default_rng(0)
    tt = Terrain.from_config(validate(PARAMS, {"resolution": 65}, "terrain"))
    nn = tt.normal(rng.uniform(-300, 300, 1000), rng.uniform(-300, 300, 1000))
    assert np.isfinite(nn).all() and (nn[:, 1] > 0).all()
    np.testing.assert_allclose(np.linalg.norm(nn, axis=-1), 1.0)


def test_procedural_is_deterministic_by_seed():
    a = fbm_value_noise(33, 17, 5)
    assert a.shape == (17, 33) and a.min() == 0.0 and a.max() == 1.0
    np.testing.assert_array_equal(a, fbm_value_noise(33, 17, 5))
    assert not np.array_equal(a, fbm_value_noise(33, 17, 6))
    t = Terrain.from_config(validate(PARAMS, {"resolution": 33, "height_scale": 10.0}, "terrain"))
    assert np.ptp(t.heights) == pytest.approx(10.0)


def test_png_8_and_16_bit_and_npz(tmp_path):
    from PIL import Image

    h16 = (np.arange(12, dtype=np.uint16).reshape(3, 4) * 5000)
    Image.fromarray(h16).save(tmp_path / "h16.png")
    np.testing.assert_allclose(load_heights(str(tmp_path / "h16.png")), h16 / 65535.0)
    h8 = (np.arange(12, dtype=np.uint8).reshape(3, 4) * 20)
    Image.fromarray(h8).save(tmp_path / "h8.png")
    np.testing.assert_allclose(load_heights(str(tmp_path / "h8.png")), h8 / 255.0)
    np.savez(tmp_path / "h.npz", height=np.ones((4, 5)) * 2.5)
    t = Terrain.from_config(validate(PARAMS, {"file": "h.npz", "height_scale": 2.0}, "terrain"), str(tmp_path))
    assert t.heights.shape == (4, 5) and t.height(0.0, 0.0) == pytest.approx(5.0)


def test_bad_files_raise_asset_error_naming_the_file(tmp_path):
    (tmp_path / "bad.png").write_bytes(b"not a png")
    np.savez(tmp_path / "noh.npz", other=np.ones((3, 3)))
    np.savez(tmp_path / "nan.npz", height=np.full((3, 3), np.nan))
    np.savez(tmp_path / "flat.npz", height=np.ones(5))
    (tmp_path / "h.tif").write_bytes(b"x")
    for name in ("bad.png", "noh.npz", "nan.npz", "flat.npz", "h.tif", "missing.png"):
        with pytest.raises(AssetError, match=name.replace(".", r"\.")):
            load_heights(str(tmp_path / name))


def test_mesh_covers_terrain_and_faces_up():
    t = Terrain.from_config(validate(PARAMS, {"resolution": 17}, "terrain"))
    m = t.mesh()
    assert m.n_vertices == 17 * 17 and m.n_triangles == 2 * 16 * 16
    p = m.positions.astype(np.float64)
    a, b, c = p[m.indices[:, 0]], p[m.indices[:, 1]], p[m.indices[:, 2]]
    assert (np.cross(b - a, c - a)[:, 1] > 0).all()
    assert m.colors.shape == (17 * 17, 4) and np.isfinite(m.colors).all()
    np.testing.assert_allclose(p[:, 1], t.height(p[:, 0], p[:, 2]), atol=1e-4)
    assert t.mesh(max_resolution=5).n_vertices == 25


def test_terrain_follow_sets_height_only():
    t = small()
    st = CrowdState.empty(4)
    st.position[:, 0] = [-5, 0, 5, 100]
    st.position[:, 2] = [2, 4, 6, 6]
    st.velocity[:, 0] = 1.0
    w = World(state=st, characters=[])
    w.resources["terrain"] = t
    w.install("terrain_follow", validate(__import__("sim.terrain_follow").terrain_follow.PARAMS, {"offset": 0.1},
                                         "effects[0]"))
    before = st.position.copy(), st.velocity.copy()
    w.step(0.1)
    np.testing.assert_allclose(st.position[:, 1], t.height(st.position[:, 0], st.position[:, 2]) + 0.1)
    np.testing.assert_array_equal(st.position[:, [0, 2]], before[0][:, [0, 2]])
    np.testing.assert_array_equal(st.velocity, before[1])
    w2 = World(state=CrowdState.empty(1), characters=[])
    with pytest.raises(ParamError, match="terrain"):
        w2.install("terrain_follow", {"offset": 0.0})


def test_params_reject_bad_values():
    for bad in ({"resolution": 1}, {"octaves": 0}, {"height_scale": -1.0}, {"size": [1.0]}):
        with pytest.raises(ParamError):
            validate(PARAMS, bad, "terrain")
    with pytest.raises(ParamError, match="size"):
        Terrain.from_config(validate(PARAMS, {"size": [0.0, 5.0]}, "terrain"))
