"""The generated characters of ``scripts/bench_peer.py``, written as GLB files both sides load.

- ``humanoid60k_4inf.glb``: ``sim.procedural.humanoid(60000)`` with every vertex skinned to FOUR joints
  (the generator gives up to three: its part's bone, the parent's and the child's; the empty slots get
  further joints of the chain -- grandparent, the hips, the chest -- at small weights, so the skinning
  cost is that of a 4-influence character everywhere);
- ``humanoid60k_1inf_59prims.glb``: ``humanoid(60000)`` rigidly skinned (each vertex to its largest
  influence, weight 1) and split into 59 primitives (each body part cut into pieces of about equal
  size, one material each), the shape of the issue's 62 K-triangle, 59-primitive character.

Both are written with the project's glTF writer (``sim.gltf.write``); the skeleton and the mesh node get one parent
(see ``_write``); the split one replaces the writer's single primitive by the pieces (the unused single-primitive data stay in the binary buffer).
Materials are single-sided (glTF's default), as exported characters usually are.

Run:  .venv/bin/python scripts/peer_models.py DIR
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

#: triangles of the generated characters
TRIANGLES = 60_000
#: primitives of the rigid character
PRIMITIVES = 59


def four_influences(ch):
    """``ch`` with every vertex weighted to four distinct joints (in place; returns ch)."""
    m, sk = ch.mesh, ch.skeleton
    par = np.asarray(sk.parents, np.int64)
    J = sk.n_joints
    jn = np.asarray(m.joints, np.int64).copy()
    w = np.asarray(m.weights, np.float64).copy()
    chest = int(np.flatnonzero(np.asarray(sk.names) == "chest")[0]) if "chest" in list(sk.names) else min(2, J - 1)
    for v in range(jn.shape[0]):
        used = [int(jn[v, k]) for k in range(4) if w[v, k] > 0]
        b = used[0]
        cands = [par[b], par[par[b]] if par[b] >= 0 else -1, 0, chest, *range(J)]
        for k in range(4):
            if w[v, k] > 0:
                continue
            c = next(int(x) for x in cands if x >= 0 and int(x) not in used)
            used.append(c)
            jn[v, k], w[v, k] = c, 0.04
    w /= w.sum(1, keepdims=True)
    m.joints = jn.astype(np.uint16)
    m.weights = w.astype(np.float32)
    return ch


def one_influence(ch):
    """``ch`` rigidly skinned: each vertex to its largest influence, weight 1 (in place)."""
    m = ch.mesh
    jn = np.asarray(m.joints, np.int64)
    w = np.asarray(m.weights, np.float64)
    top = jn[np.arange(jn.shape[0]), np.argmax(w, 1)]
    j = np.zeros_like(jn)
    j[:, 0] = top
    ww = np.zeros_like(w)
    ww[:, 0] = 1.0
    m.joints = j.astype(np.uint16)
    m.weights = ww.astype(np.float32)
    return ch


def split_primitives(indices: np.ndarray, joint_of_vertex: np.ndarray, n: int) -> list:
    """Triangle index lists of ``n`` pieces: triangles grouped by the joint of their first vertex,
    each group cut into consecutive runs, pieces allotted in proportion to the groups' sizes."""
    tri = np.asarray(indices, np.int64).reshape(-1, 3)
    key = joint_of_vertex[tri[:, 0]]
    groups = [np.flatnonzero(key == k) for k in np.unique(key)]
    sizes = np.array([len(g) for g in groups], np.float64)
    alloc = np.maximum(1, np.floor(sizes / sizes.sum() * n)).astype(int)
    while alloc.sum() < n:
        alloc[np.argmax(sizes / alloc)] += 1
    pieces = []
    for g, a in zip(groups, alloc):
        pieces += [tri[c] for c in np.array_split(g, a) if len(c)]
    return pieces


def write_models(out) -> dict:
    """Write the generated characters into ``out``; returns {name: path}. Files already there are kept."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"humanoid60k-4inf": out / "humanoid60k_4inf.glb",
             "humanoid60k-1inf-59prims": out / f"humanoid60k_1inf_{PRIMITIVES}prims.glb"}
    from sim.procedural import humanoid

    if not paths["humanoid60k-4inf"].is_file():
        _write(four_influences(humanoid(TRIANGLES, seed=3)), paths["humanoid60k-4inf"], 0)
    if not paths["humanoid60k-1inf-59prims"].is_file():
        _write(one_influence(humanoid(TRIANGLES, seed=4)), paths["humanoid60k-1inf-59prims"], PRIMITIVES)
    return paths


def _write(ch, path: Path, n: int) -> None:
    """Write ``ch`` as GLB, its mesh split into ``n`` primitives (0: one), the skeleton's root and the
    mesh node under one parent node, the skin's ``skeleton`` (as exporters such as Blender's write
    it: panda3d-gltf makes that node the Actor's Character, and a mesh outside it is not drawn)."""
    import os
    import tempfile

    import pygltflib

    from sim.gltf.write import _export_skinned, _mesh_primitive, _Writer

    w = _Writer()
    gl = _export_skinned(ch, w)
    m = ch.mesh
    pos, nrm, col = (np.asarray(a) for a in (m.positions, m.ensure_normals(), m.vertex_colors()))
    jn, wt = np.asarray(m.joints, np.uint16), np.asarray(m.weights, np.float32)
    nodes = gl["nodes"]
    roots = gl["scenes"][0]["nodes"]
    nodes.append({"name": "rig", "children": list(roots)})
    gl["scenes"][0]["nodes"] = [len(nodes) - 1]
    gl["skins"][0]["skeleton"] = len(nodes) - 1
    if not n:
        gl["meshes"][0]["primitives"][0]["material"] = 0
        gl["materials"] = [{"name": "body", "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1],
                                                                     "metallicFactor": 0.0, "roughnessFactor": 1.0}}]
    prims, mats = [], []
    for k, tri in enumerate(split_primitives(m.indices, jn[:, 0].astype(np.int64), n) if n else []):
        used, local = np.unique(tri.ravel(), return_inverse=True)
        extra = {"JOINTS_0": w.add(jn[used], "VEC4", 34962), "WEIGHTS_0": w.add(wt[used], "VEC4", 34962)}
        p = _mesh_primitive(w, pos[used], nrm[used], col[used], local.reshape(-1, 3).astype(np.uint32), extra)
        p["material"] = k
        prims.append(p)
        mats.append({"name": f"piece{k}", "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1],
                                                                    "metallicFactor": 0.0, "roughnessFactor": 1.0}})
    if n:
        gl["meshes"][0]["primitives"] = prims
        gl["materials"] = mats
    gl.update({"asset": {"version": "2.0", "generator": "crowd-sandbox scripts/peer_models.py"}, "scene": 0,
               "buffers": [{"byteLength": len(w.blob)}], "bufferViews": w.views, "accessors": w.accessors})
    doc = pygltflib.GLTF2.from_dict(gl)
    doc.set_binary_blob(bytes(w.blob))
    data = b"".join(doc.save_to_bytes())
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.replace(tmp, path)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print("usage: scripts/peer_models.py DIR", file=sys.stderr)
        sys.exit(2)
    for name, p in write_models(sys.argv[1]).items():
        print(name, p)
