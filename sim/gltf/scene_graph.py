"""The glTF node hierarchy: local and world transforms, the default scene.

Notes
-----
Follows §3.5 of the glTF 2.0 specification (2.0.1): the default scene
(``scene``, else scene 0, else every root node), nodes and hierarchy (the
nodes must form a forest: no node with two parents, no cycle) and
transformations (a column-major ``matrix`` or translation/rotation/scale).
"""
from __future__ import annotations

import numpy as np

from sim import math3d
from sim.gltf.container import _Doc, _is_int


def _node_local(doc: _Doc, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(matrix (4,4), translation (3,), rotation (4,), scale (3,)) of nodes[i]."""
    n = doc.item("nodes", i)
    doc.ctx = f"nodes[{i}]"
    try:
        if "matrix" in n:
            m = np.asarray(n["matrix"], np.float64).reshape(4, 4).T  # column-major in JSON
            t = m[:3, 3].copy()
            lin = m[:3, :3]
            s = np.linalg.norm(lin, axis=0)
            if np.linalg.det(lin) < 0:
                s[0] = -s[0]
            r = math3d.matrix_to_quat(lin / np.where(np.abs(s) > 1e-30, s, 1.0))
        else:
            t = np.asarray(n.get("translation", (0, 0, 0)), np.float64).reshape(3)
            r = np.asarray(n.get("rotation", (0, 0, 0, 1)), np.float64).reshape(4)
            s = np.asarray(n.get("scale", (1, 1, 1)), np.float64).reshape(3)
            r = math3d.quat_normalize(r)
            m = math3d.trs_matrix(t, r, s)
    except (ValueError, TypeError):
        doc.fail(f"nodes[{i}]: matrix/translation/rotation/scale have the wrong length or type")
    if not (np.all(np.isfinite(m)) and np.all(np.isfinite(r))):
        doc.fail(f"nodes[{i}]: transform contains NaN or infinite values")
    return m, t, r, s


class _Graph:
    """Parent links, world matrices and the default scene's node set."""

    def __init__(self, doc: _Doc):
        nodes = doc.items("nodes")
        self.n = len(nodes)
        self.parent = np.full(self.n, -1, np.int64)
        self.children: list[list[int]] = [[] for _ in range(self.n)]
        for i in range(self.n):
            nd = doc.item("nodes", i)
            for c in nd.get("children", []):
                if not _is_int(c) or not 0 <= c < self.n:
                    doc.fail(f"nodes[{i}].children: node {c!r} does not exist ({self.n} nodes)")
                if c == i:
                    doc.fail(f"nodes[{i}]: cyclic node hierarchy (node is its own child)")
                if self.parent[c] >= 0:
                    doc.fail(f"nodes[{c}] has two parents (nodes[{self.parent[c]}] and nodes[{i}]); the node hierarchy must be a forest")
                self.parent[c] = i
                self.children[i].append(c)
        # cycle detection: walking up from any node must end at a root
        state = np.zeros(self.n, np.int8)  # 0 unknown, 1 reaches a root
        for i in range(self.n):
            path, j = [], i
            while j >= 0 and state[j] == 0:
                if j in path:
                    doc.fail(f"nodes[{j}]: cyclic node hierarchy")
                path.append(j)
                if len(path) > self.n:
                    doc.fail(f"nodes[{j}]: cyclic node hierarchy")
                j = int(self.parent[j])
            state[path] = 1
        self.local = []
        self.trs = []
        for i in range(self.n):
            m, t, r, s = _node_local(doc, i)
            self.local.append(m)
            self.trs.append((t, r, s))
        self.world = [None] * self.n
        for i in self.topo_order():
            p = self.parent[i]
            self.world[i] = self.local[i] if p < 0 else self.world[p] @ self.local[i]
        # default scene
        scenes = doc.items("scenes")
        if scenes:
            si = doc.json.get("scene", 0)
            sc = doc.item("scenes", si, "scene")
            roots = sc.get("nodes", [])
            for r in roots:
                if not _is_int(r) or not 0 <= r < self.n:
                    doc.fail(f"scenes[{si}].nodes: node {r!r} does not exist ({self.n} nodes)")
        else:
            roots = [i for i in range(self.n) if self.parent[i] < 0]
        self.scene_nodes: list[int] = []
        stack = list(reversed(roots))
        while stack:
            i = stack.pop()
            self.scene_nodes.append(i)
            stack.extend(reversed(self.children[i]))

    def topo_order(self) -> list[int]:
        depth = np.zeros(self.n, np.int64)
        for i in range(self.n):
            d, j = 0, self.parent[i]
            while j >= 0:
                d += 1
                j = self.parent[j]
            depth[i] = d
        return [int(i) for i in np.argsort(depth, kind="stable")]

    def ancestors(self, i: int) -> list[int]:
        out, j = [], int(self.parent[i])
        while j >= 0:
            out.append(j)
            j = int(self.parent[j])
        return out
