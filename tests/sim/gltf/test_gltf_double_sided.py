"""glTF ``material.doubleSided`` (§3.9.5) becomes ``Mesh.double_sided``: a mesh is single-sided (its back
faces may be culled) only when every primitive's material is, the default material included; the writer
keeps the flag through a round trip."""
import numpy as np
import pytest
from awkward_gltf import GltfBuilder, box

from sim.gltf.load import load_gltf
from sim.gltf.write import save_glb
from sim.procedural import humanoid


def _two_boxes(path, materials):
    """Two boxes (two primitives of one static mesh); ``materials``: per primitive a material dict or None."""
    b = GltfBuilder()
    prims, mats = [], []
    for k, mat in enumerate(materials):
        p, tri = box([k * 1.0, 0, 0], [k * 1.0 + 0.5, 0.5, 0.5])
        pr = b.prim(p, tri)
        if mat is not None:
            pr["material"] = len(mats)
            mats.append(mat)
        prims.append(pr)
    b.gltf.update({"scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"name": "boxes", "mesh": 0}],
                   "meshes": [{"primitives": prims}]})
    if mats:
        b.gltf["materials"] = mats
    return b.write(path)


@pytest.mark.parametrize("materials, double", [
    ([None, None], False),                                   # the default material: single-sided
    ([{"doubleSided": False}, {}], False),
    ([{"doubleSided": True}, None], True),                   # one double-sided primitive: no culling
    ([{"doubleSided": True}, {"doubleSided": True}], True),
])
def test_double_sided_follows_every_primitive_material(tmp_path, materials, double):
    ch = load_gltf(_two_boxes(tmp_path / "boxes.glb", materials))
    assert ch.mesh.double_sided is double


def test_written_characters_keep_the_flag(tmp_path):
    ch = humanoid(800, seed=1)
    assert ch.mesh.double_sided is False
    save_glb(ch, tmp_path / "one.glb")
    assert load_gltf(tmp_path / "one.glb").mesh.double_sided is False
    ch.mesh.double_sided = True
    save_glb(ch, tmp_path / "both.glb")
    back = load_gltf(tmp_path / "both.glb")
    assert back.mesh.double_sided is True
    assert np.allclose(back.mesh.colors, ch.mesh.vertex_colors(), atol=1e-6)  # the material keeps the colours
