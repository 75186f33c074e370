"""sim.procedural: triangle budgets, watertight outward parts, skin weights, clips."""
import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from sim import procedural as P
from sim.mesh import vertex_normals
from sim.skinning import bind_pose_matrices, pose_positions, skin

GENS = [P.humanoid, P.quadruped]


@pytest.fixture(scope="module", params=GENS, ids=["humanoid", "quadruped"])
def char(request):
    return request.param(5000, seed=3)


@pytest.mark.parametrize("gen", GENS, ids=["humanoid", "quadruped"])
@pytest.mark.parametrize("n", [500, 501, 777, 5000, 23000, 85000, 200000])
def test_triangle_count_within_tolerance(gen, n):
    c = gen(n, seed=n % 7)
    assert abs(c.mesh.n_triangles - n) <= P.TRIANGLE_TOLERANCE * n
    assert c.mesh.n_triangles == c.mesh.indices.shape[0]


@pytest.mark.parametrize("bad", [499, 200001, 0, -5, 1000.5, True, "5000"])
def test_rejects_bad_triangle_counts(bad):
    with pytest.raises(ValueError, match="triangles: expected an integer in 500..=200000"):
        P.humanoid(bad)


@pytest.mark.parametrize("gen", GENS, ids=["humanoid", "quadruped"])
def test_deterministic_by_seed(gen):
    a, b, c = gen(2000, seed=5), gen(2000, seed=5), gen(2000, seed=6)
    for f in ("positions", "indices", "normals", "colors", "joints", "weights"):
        np.testing.assert_array_equal(getattr(a.mesh, f), getattr(b.mesh, f))
    assert not np.array_equal(a.mesh.colors, c.mesh.colors)


def test_mesh_arrays_are_well_formed(char):
    m = char.mesh
    assert m.positions.dtype == np.float32 and m.positions.shape == (m.n_vertices, 3)
    assert m.indices.dtype == np.uint32 and m.indices.max() < m.n_vertices
    assert m.colors.dtype == np.float32 and m.colors.shape == (m.n_vertices, 4)
    assert m.colors.min() >= 0 and m.colors.max() <= 1
    assert m.joints.dtype == np.uint16 and m.weights.dtype == np.float32
    for a in (m.positions, m.normals, m.colors, m.weights):
        assert np.all(np.isfinite(a))
    np.testing.assert_allclose(m.weights.sum(1), 1.0, atol=1e-6)
    assert m.weights.min() >= 0
    assert m.joints.max() < char.skeleton.n_joints
    np.testing.assert_allclose(np.linalg.norm(m.normals, axis=1), 1.0, atol=1e-5)


def test_parts_are_closed_consistently_oriented_and_outward(char):
    tri = char.mesh.indices.astype(np.int64)
    p = char.mesh.positions.astype(np.float64)
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    key = e[:, 0] * p.shape[0] + e[:, 1]
    rkey = e[:, 1] * p.shape[0] + e[:, 0]
    assert np.unique(key).size == key.size  # each directed edge once (no flips)
    assert np.array_equal(np.sort(key), np.sort(rkey))  # and its reverse once: closed surface
    # every connected part has positive signed volume (outward winding)
    V = p.shape[0]
    g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(V, V))
    n_comp, label = connected_components(g, directed=False)
    assert n_comp == len(P.HUMANOID_JOINTS if char.skeleton.n_joints == 21 else P.QUADRUPED_JOINTS)
    a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    vol = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0
    per = np.bincount(label[tri[:, 0]], weights=vol, minlength=n_comp)
    assert per.min() > 0
    # stored normals agree with the geometry's outward normals
    n_geo = vertex_normals(p, tri)
    assert np.einsum("ij,ij->i", n_geo, char.mesh.normals).min() > 0.99


@pytest.mark.parametrize("gen", GENS, ids=["humanoid", "quadruped"])
@pytest.mark.parametrize("n", [500, 200000])
def test_no_degenerate_triangles(gen, n):
    m = gen(n).mesh
    p = m.positions.astype(np.float64)
    t = m.indices.astype(np.int64)
    area = 0.5 * np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1)
    assert area.min() > 1e-9
    assert np.all(t[:, 0] != t[:, 1]) and np.all(t[:, 1] != t[:, 2]) and np.all(t[:, 0] != t[:, 2])


def test_bind_pose_reproduces_rest_mesh(char):
    pos, nrm = skin(char.mesh, bind_pose_matrices(char.skeleton))
    np.testing.assert_allclose(pos, char.mesh.positions, atol=1e-5)
    np.testing.assert_allclose(nrm, char.mesh.normals, atol=1e-5)


def test_humanoid_dimensions_and_skeleton():
    c = P.humanoid(5000, seed=0)
    p = c.mesh.positions
    assert 1.7 < p[:, 1].max() < 1.9
    assert abs(p[:, 1].min()) < 0.01
    assert 18 <= c.skeleton.n_joints <= 22 and c.skeleton.names[0] == "hips"
    toe = c.skeleton.joint_positions()[c.skeleton.index("l_toe")]
    assert toe[2] > 0.05  # faces +Z
    assert c.skeleton.joint_positions()[c.skeleton.index("l_hand")][0] > 0  # left is +X
    assert c.clip_names() == ["walk", "run"]


def test_quadruped_dimensions_and_skeleton():
    c = P.quadruped(5000, seed=0)
    p = c.mesh.positions
    sk = c.skeleton
    assert 23 <= sk.n_joints <= 27
    for name in ("tail_1", "neck_1", "head"):
        sk.index(name)
    chest = sk.joint_positions()[sk.index("chest")]
    shoulder_top = p[np.abs(p[:, 2] - chest[2]) < 0.1, 1].max()
    assert 1.45 < shoulder_top < 1.75
    assert abs(p[:, 1].min()) < 0.01
    head = sk.joint_positions()[sk.index("head")]
    assert head[2] > 0.8  # faces +Z
    assert 2.0 < (p[:, 2].max() - p[:, 2][p[:, 1] > 1.0].min()) < 2.8
    assert c.clip_names() == ["walk", "gallop"]


def test_clips_loop_in_place_with_plausible_speeds(char):
    sk = char.skeleton
    speeds = {}
    for name, clip in char.clips.items():
        assert clip.loop and clip.duration > 0
        assert all(ch.path == "rotation" for ch in clip.channels)  # in place: no translation keys
        t0 = clip.sample_times(sk, [0.0, clip.duration - 1e-9])
        np.testing.assert_allclose(np.abs(t0[1][0]), np.abs(t0[1][1]), atol=1e-6)  # seamless loop
        speeds[name] = clip.speed
    slow, fast = list(speeds.values())
    assert 0.6 < slow < 2.0 and fast > 1.5 * slow


def test_feet_do_not_skate_at_clip_speed():
    """Mid-stance, the stance foot moves backward relative to the root at ~Clip.speed."""
    c = P.humanoid(1000)
    sk, clip = c.skeleton, c.clips["walk"]
    j = sk.index("l_foot")
    T = clip.duration
    ts = np.array([0.25, 0.35]) * T  # left stance is phase 0 .. 0.62
    z = sk.joint_positions(*clip.sample_times(sk, ts))[:, j, 2]
    v = (z[0] - z[1]) / (ts[1] - ts[0])
    assert v == pytest.approx(clip.speed, rel=0.3)


def test_animation_moves_limbs_without_nan(char):
    name = char.clip_names()[1]
    p0, _ = pose_positions(char, name, 0.0)
    p1, n1 = pose_positions(char, name, 0.3 * char.clips[name].duration)
    assert np.all(np.isfinite(p1)) and np.all(np.isfinite(n1))
    assert np.abs(p1 - p0).max() > 0.1
    assert p1[:, 1].max() < 2.2


def test_character_helpers():
    c = P.quadruped(500)
    assert c.clip(1) is c.clips["gallop"] and c.clip("walk") is c.clips["walk"]
    assert c.clip_index("gallop") == 1
    assert c.duration("walk") == c.clips["walk"].duration
    lo, hi = c.rest_bounds()
    np.testing.assert_allclose(lo, c.mesh.positions.min(0))
    np.testing.assert_allclose(hi, c.mesh.positions.max(0))
    with pytest.raises(KeyError, match="no clip 'trot'; clips: walk, gallop"):
        c.clip("trot")
    with pytest.raises(IndexError, match="clip index 2 outside 0..1"):
        c.clip(2)
