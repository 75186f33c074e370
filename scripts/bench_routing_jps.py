"""JuPedSim side of scripts/bench_routing.py's route figure (run in the peers interpreter, never imported by the
project). The square room's evacuation runs through scripts/bench_avoidance_jps.py's ``bottleneck_scene`` job.

Reads one job as JSON on stdin, prints one JSON object on stdout. Coordinates are JuPedSim's (x, y) = the
sandbox's floor (x, z).

Job ``routes``: ``area`` (WKT of the walkable area), ``starts`` ([[x, z], ...]), ``goal`` [x, z], ``repeat`` (how
many times the timed queries run) -> ``lengths`` (the length of JuPedSim's ``RoutingEngine.compute_waypoints``
path from each start: its navigation mesh, A* over the triangles and the funnel algorithm), ``paths`` (the
waypoints), ``us_per_query`` (median over the repeats of the mean wall time of one query, microseconds).
"""
from __future__ import annotations

import json
import math
import statistics
import sys
import time


def routes(job: dict) -> dict:
    import jupedsim as jps
    import shapely

    engine = jps.RoutingEngine(shapely.from_wkt(job["area"]))
    goal = tuple(job["goal"])
    starts = [tuple(s) for s in job["starts"]]
    paths = [engine.compute_waypoints(s, goal) for s in starts]
    lengths = [sum(math.dist(a, b) for a, b in zip(p, p[1:])) for p in paths]
    per = []
    for _ in range(int(job.get("repeat", 5))):
        t = time.perf_counter()
        for s in starts:
            engine.compute_waypoints(s, goal)
        per.append((time.perf_counter() - t) / len(starts) * 1e6)
    return {"lengths": lengths, "paths": [[list(q) for q in p] for p in paths], "us_per_query": statistics.median(per)}


def main() -> int:
    job = json.load(sys.stdin)
    import jupedsim as jps

    out = {"routes": routes}[job["kind"]](job)
    out["jupedsim"] = jps.__version__
    json.dump(out, sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
