"""Shared geometry of the routing tests: the U-trap (scenes/u_trap.toml's walls) and the exact shortest path
computed independently of sim.routing: a visibility graph over the corners of the walkable area shrunk by the
clearance (shapely, round joins of 16 segments per quarter circle), Dijkstra from the start."""
import heapq
import math

import numpy as np

U_BOXES = [{"center": [0.0, 4.0], "size": [8.0, 0.3]}, {"center": [0.0, -4.0], "size": [8.0, 0.3]},
           {"center": [4.0, 0.0], "size": [0.3, 8.3]}]
U_BOUNDS = [-15.0, -10.0, 16.0, 10.0]
U_GOAL = (10.0, 0.0)


def shifted_boxes(boxes, dx, dz):
    return [{**b, "center": [b["center"][0] + dx, b["center"][1] + dz]} for b in boxes]


class ExactPaths:
    """Shortest paths in ``area`` (a shapely polygon) kept ``clearance`` from its boundary."""

    def __init__(self, area, clearance: float):
        import shapely

        self.free = area.buffer(-clearance, quad_segs=16)
        self.cover = self.free.buffer(1e-7)
        shapely.prepare(self.cover)
        self.corners = [c for p in getattr(self.free, "geoms", [self.free])
                        for ring in [p.exterior, *p.interiors] for c in list(ring.coords)[:-1]]

    def sees(self, a, b) -> bool:
        import shapely

        return bool(self.cover.covers(shapely.LineString([a, b])))

    def length(self, start, goal) -> float:
        nodes = [tuple(map(float, start)), tuple(map(float, goal))] + self.corners
        dist = [math.inf] * len(nodes)
        dist[0] = 0.0
        heap, done = [(0.0, 0)], [False] * len(nodes)
        while heap:
            d, k = heapq.heappop(heap)
            if done[k]:
                continue
            done[k] = True
            if k == 1:
                return d
            for m in range(len(nodes)):
                if not done[m]:
                    nd = d + math.dist(nodes[k], nodes[m])
                    if nd < dist[m] and self.sees(nodes[k], nodes[m]):
                        dist[m] = nd
                        heapq.heappush(heap, (nd, m))
        return math.inf

    def in_open_space(self, xz) -> np.ndarray:
        import shapely

        xz = np.asarray(xz, np.float64).reshape(-1, 2)
        return shapely.contains_xy(self.free, xz[:, 0], xz[:, 1])
