"""Shared helpers of the glTF tests (tests/sim/gltf): a tiny independent glTF
writer, hand-built characters, round-trip checks and the real models.

Real models come from the ``shared/assets`` folder beside the checkout (or
``$CROWD_ASSETS``) and are skipped when absent; every other test builds its
glTF files itself, so the suite runs anywhere.
"""
from __future__ import annotations

import base64
import json
import os
from pathlib import Path

import numpy as np
import pytest

from gltf_builder import GltfBuilder, write_glb  # noqa: F401 (re-exported to the tests)

from sim import math3d
from sim.character import SkinnedCharacter
from sim.clip import Channel, Clip
from sim.gltf.load import load_gltf
from sim.mesh import Mesh
from sim.skeleton import Skeleton

REPO = Path(__file__).resolve().parents[3]
ASSETS = Path(os.environ.get("CROWD_ASSETS", REPO / ".." / "shared" / "assets"))


def _have_from_meshes() -> bool:
    from sim import keyframes

    return hasattr(keyframes, "from_meshes")


needs_keyframes = pytest.mark.skipif(
    not _have_from_meshes(), reason="sim.keyframes.from_meshes is not implemented yet (engineer A)"
)


def skin_positions(mesh: Mesh, mats: np.ndarray) -> np.ndarray:
    """Plain LBS of mesh positions with (J,4,4) skinning matrices -> (V,3)."""
    p = np.c_[mesh.positions.astype(np.float64), np.ones(mesh.n_vertices)]
    M = np.einsum("vk,vkij->vij", mesh.weights.astype(np.float64), mats[mesh.joints.astype(np.int64)])
    return np.einsum("vij,vj->vi", M, p)[:, :3]


def write_gltf(path: Path, gltf: dict, blob: bytes, external: str | None = None) -> Path:
    g = json.loads(json.dumps(gltf))
    if external:
        (path.parent / external).write_bytes(blob)
        g["buffers"][0]["uri"] = external
    else:
        g["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
    path.write_text(json.dumps(g))
    return path


def box_triangles():
    """A unit quad (2 triangles) plus a single extra vertex: positions, indices."""
    p = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    i = np.array([0, 1, 2, 0, 2, 3], np.uint32)
    return p, i


def simple_gltf(**over):
    """One static quad mesh node; keyword overrides patch the primitive."""
    b = GltfBuilder()
    p, i = box_triangles()
    prim = {"attributes": {"POSITION": b.acc(p, "VEC3", min=[0, 0, 0], max=[1, 1, 0])}, "indices": b.acc(i, "SCALAR")}
    prim.update(over)
    b.gltf.update({"scenes": [{"nodes": [0]}], "scene": 0, "nodes": [{"mesh": 0}], "meshes": [{"primitives": [prim]}]})
    return b


def stacked_box_character(with_root: bool = True) -> SkinnedCharacter:
    """A 3-joint chain skinning a column of three boxes, with LINEAR, STEP and
    CUBICSPLINE clips and a non-identity root transform."""
    rings = []
    for k in range(4):
        y = float(k)
        rings += [[-0.2, y, -0.2], [0.2, y, -0.2], [0.2, y, 0.2], [-0.2, y, 0.2]]
    pos = np.array(rings, np.float32)
    tris = []
    for k in range(3):
        a, b = 4 * k, 4 * (k + 1)
        for s in range(4):
            s1 = (s + 1) % 4
            tris += [[a + s, a + s1, b + s1], [a + s, b + s1, b + s]]
    tris += [[0, 2, 1], [0, 3, 2], [12, 13, 14], [12, 14, 15]]
    idx = np.array(tris, np.uint32)
    joints = np.zeros((16, 4), np.uint16)
    weights = np.zeros((16, 4), np.float32)
    for v in range(16):
        ring = v // 4
        j0 = min(ring, 2)
        j1 = max(ring - 1, 0)
        joints[v] = (j0, j1, 0, 0)
        weights[v] = (0.75, 0.25, 0, 0) if j0 != j1 else (1, 0, 0, 0)
    colors = np.tile(np.array([0.2, 0.5, 0.9, 1.0], np.float32), (16, 1))
    colors[8:] = (0.9, 0.3, 0.1, 1.0)
    mesh = Mesh(positions=pos, indices=idx, colors=colors, joints=joints, weights=weights)
    mesh.ensure_normals()
    root = math3d.trs_matrix([1.0, 0.5, -2.0], math3d.quat_from_axis_angle([0, 1, 0], 0.3), [0.5, 0.5, 0.5])
    sk = Skeleton(
        names=["hip", "spine", "head"],
        parents=np.array([-1, 0, 1], np.int32),
        rest_translation=np.array([[0, 0, 0], [0, 1, 0], [0, 1, 0]], np.float64),
        rest_rotation=np.tile([0.0, 0, 0, 1], (3, 1)),
        rest_scale=np.ones((3, 3)),
        inverse_bind=np.tile(np.eye(4), (3, 1, 1)),
        root_transform=root if with_root else None,
    )
    sk.inverse_bind = math3d.invert_affine(sk.global_matrices(*sk.rest_pose()))
    t = np.array([0.0, 0.5, 1.0])
    bend = np.stack([math3d.quat_from_axis_angle([0, 0, 1], a) for a in (0.0, 0.6, 0.0)])
    lin = Clip("bend", 1.0, [Channel(1, "rotation", t, bend, "LINEAR"), Channel(0, "translation", t, np.array([[0, 0, 0], [0.3, 0, 0], [0, 0, 0]]), "LINEAR")])
    step = Clip("step", 1.2, [Channel(2, "scale", t, np.array([[1, 1, 1], [1.5, 1.5, 1.5], [1, 1, 1]]), "STEP")], loop=False)
    cub_vals = np.zeros((3, 3, 3))
    cub_vals[:, 1] = [[0, 1, 0], [0.2, 1.1, 0], [0, 1, 0]]
    cub_vals[:, 0] = [[0, 0, 0], [0.5, 0, 0], [0, 0, 0]]
    cub_vals[:, 2] = [[0, 0, 0], [-0.5, 0.1, 0], [0, 0, 0]]
    cub = Clip("wobble", 1.0, [Channel(1, "translation", t, cub_vals, "CUBICSPLINE")])
    return SkinnedCharacter(name="box3", mesh=mesh, skeleton=sk, clips={"bend": lin, "step": step, "wobble": cub})


def assert_round_trip(a: SkinnedCharacter, b: SkinnedCharacter, tol: float = 1e-6):
    ma, mb = a.mesh, b.mesh
    np.testing.assert_allclose(mb.positions, ma.positions, atol=tol)
    np.testing.assert_array_equal(mb.indices, ma.indices)
    np.testing.assert_allclose(mb.weights, ma.weights, atol=tol)
    used = ma.weights > 0
    np.testing.assert_array_equal(mb.joints[used], ma.joints[used])
    np.testing.assert_allclose(mb.colors, ma.vertex_colors(), atol=tol)
    sa, sb = a.skeleton, b.skeleton
    assert sb.names == sa.names
    np.testing.assert_array_equal(sb.parents, sa.parents)
    np.testing.assert_allclose(sb.inverse_bind, sa.inverse_bind, atol=tol)
    ra = np.eye(4) if sa.root_transform is None else sa.root_transform
    np.testing.assert_allclose(sb.root_transform, ra, atol=tol)
    assert list(b.clips) == list(a.clips)
    for name, ca in a.clips.items():
        cb = b.clips[name]
        assert cb.duration == pytest.approx(ca.duration, abs=tol)
        assert cb.loop == ca.loop
        assert [c.interpolation for c in cb.channels] == [c.interpolation for c in ca.channels]
        times = np.linspace(0.0, ca.duration, 17)
        for xa, xb in zip(ca.sample_times(sa, times), cb.sample_times(sb, times)):
            np.testing.assert_allclose(xb, xa, atol=tol)



# --------------------------------------------------------------------------- real assets

ASSET_EXPECT = {
    # file: (kind, joints, clip names, triangles)
    "Fox.glb": ("skinned", 24, ["Survey", "Walk", "Run"], 576),
    "CesiumMan.glb": ("skinned", 19, ["anim0"], 4672),
    "RiggedFigure.glb": ("skinned", 19, ["anim0"], 256),
    "RiggedSimple.glb": ("skinned", 2, ["anim0"], 188),
    "Horse.glb": ("keyframed", 0, ["horse_A_"], 984),
    "Flamingo.glb": ("keyframed", 0, ["flamingo_flyA_"], 542),
}


def _asset(name: str) -> Path:
    p = ASSETS / name
    if not p.is_file():
        pytest.skip(f"{p} is absent: the shared glTF test assets live in ../shared/assets beside the checkout (or set CROWD_ASSETS)")
    if ASSET_EXPECT[name][0] == "keyframed" and not _have_from_meshes():
        pytest.skip("sim.keyframes.from_meshes is not implemented yet (engineer A)")
    return p


_loaded: dict = {}


def _load_asset(name):
    if name not in _loaded:
        _loaded[name] = load_gltf(_asset(name))
    return _loaded[name]
