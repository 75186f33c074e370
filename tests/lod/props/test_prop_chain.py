"""lod.props: prop chains (fast-simplification levels, sampled Hausdorff errors, cache), the
pixels-of-error choice of levels, culling, obstacle solids."""
import numpy as np
import pytest
from prop_files import write_prop

from lod.props.chain import cached_chain, chain_key, hausdorff
from lod.props.select import WorldSelector, choose_prop_levels, pixels_per_metre
from lod.props.solids import GroundRep, obstacle_solids, triangulate_polygon
from lod.view import Camera
from sim.obstacles import ObstacleSet
from sim.props import load_prop_mesh, model_rows


@pytest.fixture(scope="module")
def blob(tmp_path_factory):
    """A 1280-triangle sphere-like prop (an icosphere) and its chain."""
    p = write_prop(tmp_path_factory.mktemp("props") / "blob", "ply", size=(1.0, 1.0, 1.0), subdivisions=3)
    mesh = load_prop_mesh(p)
    return mesh, cached_chain(mesh, "props:blob", cache=False)


def test_chain_levels_shrink_and_errors_are_monotone(blob):
    mesh, rep = blob
    assert rep.n_levels >= 4
    assert rep.level_count[0] == mesh.n_triangles == 1280
    assert (np.diff(rep.level_count) < 0).all()
    assert rep.level_error[0] == 0.0 and (np.diff(rep.level_error) >= 0).all() and (rep.level_error[1:] > 0).all()
    assert rep.indices.shape == (int(rep.level_count.sum()), 3) and int(rep.indices.max()) < len(rep.positions)
    assert np.isfinite(rep.positions).all() and np.isfinite(rep.normals).all()


def test_level_errors_bound_an_independent_denser_measure(blob):
    """Each level's stored error is at least the Hausdorff distance measured again with other,
    denser samples (the stored one carries lod.props.chain.ERROR_SAFETY)."""
    mesh, rep = blob
    v0, f0 = mesh.positions, mesh.faces
    for lvl in range(1, rep.n_levels):
        tri = rep.indices[rep.level_first[lvl]:rep.level_first[lvl] + rep.level_count[lvl]]
        v, f = rep.positions.astype(np.float64), tri.astype(np.int64)
        again = hausdorff(v0, f0, v, f, samples=16000, seed=123, k=32)
        assert again <= rep.level_error[lvl], (lvl, again, rep.level_error[lvl])


@pytest.mark.parametrize("poe", [0.5, 1.0, 4.0])
def test_selected_levels_keep_their_projected_error_within_poe(blob, poe):
    _, rep = blob
    size = (640, 360)
    hits = set()
    for dist in np.geomspace(1.2, 400.0, 40):
        cam = Camera.look_at((0.0, 0.5, dist), (0.0, 0.5, 0.0), fov_y=50.0)
        rows = model_rows(np.array([[0.0, 0.0, 0.0]]), np.zeros(1), np.ones(1))
        rows[:, :, 3] -= cam.position
        lvl = int(choose_prop_levels(rep.level_error, rows, rep.sphere, pixels_per_metre(size[1], 50.0), poe)[0])
        hits.add(lvl)
        c = rep.sphere[:3] + rows[0, :, 3]
        d = np.linalg.norm(c) - rep.sphere[3]
        px = rep.level_error * pixels_per_metre(size[1], 50.0) / d
        assert px[lvl] <= poe + 1e-9  # the selected level is within the rule
        if lvl + 1 < rep.n_levels:
            assert px[lvl + 1] > poe  # and it is the coarsest such level
    assert len(hits) >= 3  # the distances span several levels


def test_same_rule_as_the_characters_chains(blob):
    from lod.chains.mode import choose_levels

    _, rep = blob
    rng = np.random.default_rng(3)
    rows = np.zeros((200, 3, 4))
    a = rng.uniform(0, 2 * np.pi, 200)
    s = rng.uniform(0.2, 3.0, 200)
    rows[:, 0, 0], rows[:, 0, 2], rows[:, 2, 0], rows[:, 2, 2] = np.cos(a) * s, np.sin(a) * s, -np.sin(a) * s, np.cos(a) * s
    rows[:, 1, 1] = s
    rows[:, :, 3] = rng.uniform(-200, 200, (200, 3))
    for poe in (0.5, 2.0):
        assert (choose_prop_levels(rep.level_error, rows, rep.sphere, 500.0, poe)
                == choose_levels(rep.level_error, rows, rep.sphere, 500.0, poe)).all()


def test_chain_cache_is_used_and_a_corrupt_entry_rebuilt(blob, tmp_path):
    mesh, rep = blob
    a = cached_chain(mesh, "k", directory=tmp_path)
    files = list(tmp_path.glob("props-*.npz"))
    assert len(files) == 1 and chain_key(mesh, 8, 0.5) in files[0].name
    b = cached_chain(mesh, "k", directory=tmp_path)
    assert np.array_equal(a.indices, b.indices) and np.array_equal(a.level_error, b.level_error)
    files[0].write_bytes(b"garbage")
    c = cached_chain(mesh, "k", directory=tmp_path)
    assert np.array_equal(a.positions, c.positions)


def test_selector_culls_counts_and_keeps_far_instances_precise(blob):
    _, rep = blob
    far = 1e6
    pos = np.array([[far, 0.0, far], [far + 3.0, 0.0, far], [far, 0.0, far + 500.0]])  # last one is behind
    rows = model_rows(pos, np.zeros(3), np.ones(3))
    sel = WorldSelector([(rep, rows)], GroundRep())
    cam = Camera.look_at((far + 1.5, 1.0, far + 10.0), (far + 1.5, 0.5, far), fov_y=50.0)
    batches, stats = sel.select(cam, (320, 180), poe=1.0)
    assert stats["props_instances"] == 2 and stats["props_culled"] == 1
    props = [b for b in batches if b.rep == "props:blob"]
    assert stats["props"] == sum(b.triangles for b in props)
    data = np.concatenate([b.instance_data for b in props])
    assert np.isfinite(data).all()
    # camera-relative translations are exact, not rounded at 1e6 (float32 spacing there is 0.0625)
    assert sorted(np.round(data[:, 3], 6).tolist()) == [-1.5, 1.5]
    ground = [b for b in batches if b.rep == "world:ground"]
    assert len(ground) == 1 and ground[0].instance_data[0, 7] == pytest.approx(-1.0)
    full, _ = sel.select(cam, (320, 180), poe=1.0, full_detail=True)
    assert all(b.level == 0 for b in full)


def test_triangulation_of_a_concave_polygon_keeps_its_area():
    pts = np.array([[0, 0], [4, 0], [4, 4], [2, 1], [0, 4]], float)  # an arrow notch
    for p in (pts, pts[::-1]):
        t = triangulate_polygon(p)
        a = p[t]
        u, v = a[:, 1] - a[:, 0], a[:, 2] - a[:, 0]
        area = 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]).sum()
        assert len(t) == 3 and area == pytest.approx(10.0)


def test_obstacle_solids_cover_their_shapes_and_skip_hidden_ones():
    obs = ObstacleSet(circles=[{"center": [5.0, 5.0], "radius": 1.0, "height": 2.0}],
                      boxes=[{"center": [0.0, 0.0], "size": [2.0, 1.0], "yaw": 30.0, "height": 0.5},
                             {"center": [9.0, 0.0], "size": [1.0, 1.0], "visible": False}],
                      polygons=[{"points": [[0, 10], [3, 10], [0, 13]], "height": 1.0}])
    rep, rows = obstacle_solids(obs)
    world = rep.positions.astype(np.float64) + rows[0, :, 3]
    assert np.allclose(world[:, 1].max(), 2.0) and world[:, 1].min() < 0.0
    assert not ((np.abs(world[:, 0] - 9.0) < 0.6) & (np.abs(world[:, 2]) < 0.6)).any()  # hidden box
    # the circle's prism circumscribes the circle: its top cap covers every point of the disc
    top = world[(world[:, 1] > 1.99) & (np.hypot(world[:, 0] - 5, world[:, 2] - 5) < 2)]
    r = np.hypot(top[:, 0] - 5, top[:, 2] - 5)
    assert len(top) and r.min() >= 1.0 - 1e-9  # every rim vertex is outside the circle: the polygon holds it
    assert obstacle_solids(ObstacleSet()) is None


def test_degenerate_props_give_a_valid_single_level_chain(tmp_path):
    from sim.props import PropMesh

    one = PropMesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]), np.ones((3, 4), np.float32))
    rep = cached_chain(one, "one", cache=False)
    assert rep.n_levels == 1 and rep.level_count.tolist() == [1] and np.isfinite(rep.normals).all()
    # coincident corners (zero-area triangles) beside a real one: the zero-area ones are dropped
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0]])
    rep = cached_chain(PropMesh(pts, np.array([[0, 1, 2], [0, 3, 3], [0, 0, 0]]), np.ones((4, 4), np.float32)),
                       "deg", cache=False)
    assert rep.level_count[0] == 1 and np.isfinite(rep.positions).all() and np.isfinite(rep.sphere).all()
