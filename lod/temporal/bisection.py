"""Rivara/Bänsch bisection of conforming triangulations: refine and coarsen.

A forest of triangle hierarchies over a conforming *root complex*. Every
triangle carries a *refinement edge*; bisecting a triangle inserts a vertex on
that edge and the two children inherit, as their refinement edges, the two
edges of the parent opposite the new vertex (newest-vertex bisection, Fig. 2).
Refinement follows Definition 1: bisect the marked triangles, then repeatedly
mark and bisect every non-conforming triangle (one with a hanging vertex on an
edge) until the triangulation is conforming again. Coarsening merges a
*diamond* (all active triangles sharing one refinement edge, each bisected
once into two leaves) back into its parents, which keeps the mesh conforming.

Storage is flat numpy arrays (structure of arrays, index = node id) grown by
doubling; node ids are persistent, so a node coarsened away and refined again
gets its old children back, and nodes are identified across hierarchies by
their root and child path (see :mod:`lod.temporal.interpolating`).

Convention: a triangle ``(v0, v1, v2)`` has refinement edge ``(v0, v1)`` and
apex (newest vertex) ``v2``. Bisecting at ``m = mid(v0, v1)`` gives the
children ``(v2, v0, m)`` and ``(v1, v2, m)``; both keep the orientation of the
parent and have ``m`` as their newest vertex.

Notes
-----
Friedrich, Polthier & Schmies, "Smooth view-dependent level-of-detail control
by interpolating triangle hierarchies" (after Visualization '98), §2.1,
Definition 1 and Fig. 2; E. Bänsch, "Local mesh refinement in 2 and 3
dimensions", IMPACT 1991; M. Rivara, IJNME 1984 (angles stay >= half the
smallest initial angle when root refinement edges are the longest edges).
"""
from __future__ import annotations

import numpy as np

#: initial capacity (nodes / vertices) of a forest; arrays double when full
BISECTION_INIT_CAPACITY = 256


def _ekey(a: int, b: int) -> tuple:
    return (a, b) if a < b else (b, a)


class BisectionForest:
    """A conforming triangulation refined by Rivara/Bänsch bisection.

    Parameters
    ----------
    vertices : (V, D) float64 root vertex coordinates (D = 2 or 3); new vertices
        are placed at edge midpoints (callers may move them afterwards).
    triangles : (T, 3) int root triangles of a conforming complex.
    refinement_edges : (T,) int in {0, 1, 2} or None
        Local index ``k`` of each root's refinement edge ``(tri[k], tri[k+1 mod 3])``;
        None picks each root's longest edge (Rivara's choice, which gives the
        angle bound).

    Attributes
    ----------
    tri : (N, 3) int64 node triangles (refinement edge = columns 0, 1)
    parent, child : (N,) int64; ``child`` is the first of two consecutive
        children or -1 (never bisected)
    level, root : (N,) int64, depth below and index of the root
    active : (N,) bool, node belongs to the current hierarchy
    leaf : (N,) bool, node is a leaf of the current hierarchy (active, unbisected)
    verts : (V, D) float64, vparents : (V, 2) int64 (-1 for roots)
    """

    def __init__(self, vertices, triangles, refinement_edges=None):
        v = np.asarray(vertices, np.float64)
        t = np.asarray(triangles, np.int64).reshape(-1, 3)
        if v.ndim != 2 or v.shape[1] not in (2, 3) or not np.isfinite(v).all():
            raise ValueError(f"BisectionForest: vertices must be finite (V, 2|3), got shape {v.shape}")
        if t.size and (t.min() < 0 or t.max() >= v.shape[0]):
            raise ValueError("BisectionForest: triangle indices out of range")
        if refinement_edges is None:
            a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
            lens = np.stack([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1),
                             np.linalg.norm(a - c, axis=1)], 1)
            refinement_edges = np.argmax(lens, axis=1) if t.size else np.zeros(0, np.int64)
        k = np.asarray(refinement_edges, np.int64).reshape(-1)
        if k.shape[0] != t.shape[0] or (k.size and (k.min() < 0 or k.max() > 2)):
            raise ValueError("BisectionForest: refinement_edges must be (T,) ints in {0, 1, 2}")
        rows = np.arange(t.shape[0])
        t = np.stack([t[rows, k], t[rows, (k + 1) % 3], t[rows, (k + 2) % 3]], 1)
        self.n_roots = t.shape[0]
        cap = max(BISECTION_INIT_CAPACITY, 2 * t.shape[0])
        self.tri = np.zeros((cap, 3), np.int64)
        self.parent = np.full(cap, -1, np.int64)
        self.child = np.full(cap, -1, np.int64)
        self.level = np.zeros(cap, np.int64)
        self.root = np.zeros(cap, np.int64)
        self.active = np.zeros(cap, bool)
        self.leaf = np.zeros(cap, bool)
        self.n_nodes = t.shape[0]
        self.tri[: self.n_nodes] = t
        self.root[: self.n_nodes] = rows
        self.active[: self.n_nodes] = True
        self.leaf[: self.n_nodes] = True
        vcap = max(BISECTION_INIT_CAPACITY, 2 * v.shape[0])
        self.verts = np.zeros((vcap, v.shape[1]), np.float64)
        self.verts[: v.shape[0]] = v
        self.vparents = np.full((vcap, 2), -1, np.int64)
        self.n_verts = v.shape[0]
        self.n_root_verts = v.shape[0]
        self.vuse = np.zeros(vcap, np.int64)  # active leaves using each vertex
        np.add.at(self.vuse, t.reshape(-1), 1)
        self.mid: dict = {}  # edge key -> midpoint vertex id (persistent)
        self.edge_leaves: dict = {}  # edge key -> set of active leaves having that edge
        self.redge_nodes: dict = {}  # refinement edge key -> node ids with that refinement edge
        for i in range(self.n_nodes):
            self._add_leaf_edges(i)
            self.redge_nodes.setdefault(_ekey(t[i, 0], t[i, 1]), []).append(i)
        self.n_bisections = 0

    # ------------------------------------------------------------------ storage
    def _grow_nodes(self, need: int) -> None:
        cap = self.tri.shape[0]
        if need <= cap:
            return
        new = max(need, 2 * cap)
        for name in ("tri", "parent", "child", "level", "root", "active", "leaf"):
            a = getattr(self, name)
            fill = -1 if name in ("parent", "child") else 0
            b = np.full((new,) + a.shape[1:], fill, a.dtype)
            b[:cap] = a
            setattr(self, name, b)

    def _new_vertex(self, a: int, b: int) -> int:
        if self.n_verts == self.verts.shape[0]:
            new = 2 * self.verts.shape[0]
            for name, fill in (("verts", 0.0), ("vparents", -1), ("vuse", 0)):
                a_ = getattr(self, name)
                b_ = np.full((new,) + a_.shape[1:], fill, a_.dtype)
                b_[: a_.shape[0]] = a_
                setattr(self, name, b_)
        m = self.n_verts
        self.verts[m] = 0.5 * (self.verts[a] + self.verts[b])
        self.vparents[m] = (a, b)
        self.n_verts += 1
        return m

    def _add_leaf_edges(self, i: int) -> None:
        a, b, c = (int(x) for x in self.tri[i])
        for e in (_ekey(a, b), _ekey(b, c), _ekey(c, a)):
            self.edge_leaves.setdefault(e, set()).add(i)

    def _remove_leaf_edges(self, i: int) -> None:
        a, b, c = (int(x) for x in self.tri[i])
        for e in (_ekey(a, b), _ekey(b, c), _ekey(c, a)):
            s = self.edge_leaves.get(e)
            if s is not None:
                s.discard(i)
                if not s:
                    del self.edge_leaves[e]

    # ------------------------------------------------------------------ queries
    def leaves(self) -> np.ndarray:
        """(L,) int64 ids of the current leaf triangles, ascending."""
        return np.flatnonzero(self.leaf[: self.n_nodes])

    def leaf_triangles(self) -> np.ndarray:
        """(L, 3) int64 vertex indices of the current leaves (refinement edge first)."""
        return self.tri[self.leaves()]

    def refinement_midpoint(self, i: int) -> int:
        """Vertex id of the midpoint of node ``i``'s refinement edge, or -1 if never created."""
        return self.mid.get(_ekey(int(self.tri[i, 0]), int(self.tri[i, 1])), -1)

    def _is_hanging(self, i: int) -> bool:
        a, b, c = (int(x) for x in self.tri[i])
        for e in (_ekey(a, b), _ekey(b, c), _ekey(c, a)):
            m = self.mid.get(e, -1)
            if m >= 0 and self.vuse[m] > 0:
                return True
        return False

    def hanging_leaves(self) -> np.ndarray:
        """(k,) int64 non-conforming leaves: a leaf edge whose midpoint is in use."""
        return np.asarray([i for i in self.leaves() if self._is_hanging(int(i))], np.int64)

    def path(self, i: int) -> tuple:
        """(root, bits...) canonical address of node ``i``: its root and the
        child index (0/1) taken at each level. Two forests over the same root
        complex with the same root refinement edges (Definition 2) give the same
        triangle the same path."""
        bits = []
        while self.parent[i] >= 0:
            p = int(self.parent[i])
            bits.append(int(i - self.child[p]))
            i = p
        return (int(self.root[i]),) + tuple(reversed(bits))

    # ------------------------------------------------------------------ refinement
    def bisect(self, i: int) -> int:
        """Bisect leaf ``i`` at its refinement edge (no closure); returns the
        first child id. The caller is responsible for conformity."""
        if not self.leaf[i]:
            raise ValueError(f"BisectionForest.bisect: node {i} is not a leaf")
        a, b, c = (int(x) for x in self.tri[i])
        e = _ekey(a, b)
        m = self.mid.get(e)
        if m is None:
            m = self._new_vertex(a, b)
            self.mid[e] = m
        ch = int(self.child[i])
        if ch < 0:
            self._grow_nodes(self.n_nodes + 2)
            ch = self.n_nodes
            self.n_nodes += 2
            self.tri[ch] = (c, a, m)
            self.tri[ch + 1] = (b, c, m)
            for k in (ch, ch + 1):
                self.parent[k] = i
                self.level[k] = self.level[i] + 1
                self.root[k] = self.root[i]
                t = self.tri[k]
                self.redge_nodes.setdefault(_ekey(int(t[0]), int(t[1])), []).append(k)
            self.child[i] = ch
        self._remove_leaf_edges(i)
        self.leaf[i] = False
        self.vuse[[a, b, c]] -= 1
        for k in (ch, ch + 1):
            self.active[k] = True
            self.leaf[k] = True
            self._add_leaf_edges(k)
            self.vuse[self.tri[k]] += 1
        self.n_bisections += 1
        return ch

    def refine(self, marked) -> int:
        """Definition 1: bisect the marked leaves, then bisect every
        non-conforming leaf until the triangulation is conforming.

        Parameters
        ----------
        marked : iterable of int node ids (non-leaves are ignored)

        Returns
        -------
        int, number of bisections performed
        """
        n0 = self.n_bisections
        s = [int(i) for i in marked if 0 <= int(i) < self.n_nodes and self.leaf[int(i)]]
        while s:
            nxt = set()
            for i in s:
                if not self.leaf[i]:
                    continue
                a, b = int(self.tri[i, 0]), int(self.tri[i, 1])
                ch = self.bisect(i)
                # non-conforming now: leaves still holding the bisected edge, and a
                # child that inherited an edge its neighbour had already split
                for j in self.edge_leaves.get(_ekey(a, b), ()):
                    nxt.add(j)
                for j in (ch, ch + 1):
                    if self._is_hanging(j):
                        nxt.add(j)
            s = sorted(nxt)
        return self.n_bisections - n0

    def refine_where(self, predicate, max_level: int = 30) -> int:
        """Refine repeatedly every leaf for which ``predicate(forest, leaf_ids) -> (k,) bool``
        holds (with closure), up to ``max_level``; returns bisections done."""
        n0 = self.n_bisections
        while True:
            lv = self.leaves()
            lv = lv[self.level[lv] < max_level]
            if lv.size == 0:
                break
            m = np.asarray(predicate(self, lv), bool)
            if not m.any():
                break
            self.refine(lv[m])
        return self.n_bisections - n0

    # ------------------------------------------------------------------ coarsening
    def can_coarsen(self, i: int) -> bool:
        """Node ``i`` can be merged: it and every active node sharing its
        refinement edge are bisected exactly once (children are leaves)."""
        if not self.active[i] or self.leaf[i]:
            return False
        e = _ekey(int(self.tri[i, 0]), int(self.tri[i, 1]))
        for q in self.redge_nodes[e]:
            if not self.active[q]:
                continue
            ch = self.child[q]
            if self.leaf[q] or ch < 0 or not (self.leaf[ch] and self.leaf[ch + 1]):
                return False
        return True

    def _merge(self, i: int) -> list:
        e = _ekey(int(self.tri[i, 0]), int(self.tri[i, 1]))
        merged = []
        for q in self.redge_nodes[e]:
            if not self.active[q]:
                continue
            ch = int(self.child[q])
            for k in (ch, ch + 1):
                self._remove_leaf_edges(k)
                self.vuse[self.tri[k]] -= 1
                self.active[k] = False
                self.leaf[k] = False
            self.leaf[q] = True
            self._add_leaf_edges(q)
            self.vuse[self.tri[q]] += 1
            merged.append(q)
        return merged

    def coarsen(self, marked) -> int:
        """Merge the marked bisected nodes where conformity allows (the whole
        diamond of a node is merged together), repeating finest first until
        no marked node can be merged; returns the number of merges."""
        todo = {int(i) for i in marked if 0 <= int(i) < self.n_nodes}
        n = 0
        changed = True
        while changed:
            changed = False
            for i in sorted(todo, key=lambda j: -self.level[j]):
                if i in todo and self.can_coarsen(i):
                    for q in self._merge(i):
                        todo.discard(q)
                        n += 1
                    changed = True
        return n

    def coarsen_all(self) -> int:
        """Coarsen back to the root complex; returns the number of merges."""
        act = np.flatnonzero(self.active[: self.n_nodes] & ~self.leaf[: self.n_nodes])
        return self.coarsen(act)


def triangle_angles(verts: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """(T, 3) float64 interior angles (radians) of triangles ``tris`` over ``verts``."""
    p = np.asarray(verts, np.float64)[np.asarray(tris, np.int64)]
    out = np.empty(p.shape[:2])
    for k in range(3):
        u = p[:, (k + 1) % 3] - p[:, k]
        w = p[:, (k + 2) % 3] - p[:, k]
        c = np.sum(u * w, 1) / np.maximum(np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1), 1e-300)
        out[:, k] = np.arccos(np.clip(c, -1.0, 1.0))
    return out
