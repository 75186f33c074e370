"""JuPedSim side of scripts/bench_avoidance.py (run in the peers interpreter, never imported by the project).

Reads one job as JSON on stdin, runs it in JuPedSim's CollisionFreeSpeedModel (Tordeux, Chraibi & Seyfried 2016)
and prints one JSON object on stdout. Coordinates are JuPedSim's (x, y) = the sandbox's floor (x, z).

Jobs (keys besides ``kind``):

- ``bottleneck``: ``positions`` (.npy path, (n, 2)), ``dt``, ``model`` (the four CollisionFreeSpeedModel
  parameters), ``agent`` (time_gap, desired_speed, radius), ``room`` [x0, x1, z0, z1], ``door`` [x_wall0, x_wall1,
  half_width], ``exits`` (list of [x0, x1, z0, z1] exit rectangles, agent i takes exit i mod len), ``waypoint``
  [x, z, distance], ``outside`` [x1, z0, z1] (walkable area beyond the wall up to x1), ``line_x``, ``max_time``
  -> ``crossing_times`` (first time each agent's x exceeds line_x, seconds, null if never), ``steps``,
  ``min_distance`` (smallest centre distance of any pair at any sampled step), ``wall_seconds``.
- ``bottleneck_scene``: ``positions``, ``dt``, ``model``, ``agent``, ``polygons`` (wall polygons [[x, z], ...]),
  ``circles`` ([x, z, r]), ``paths`` (goals paths: waypoints, the last one the exit), ``arrive_radius``, ``line_x``,
  ``max_time`` -> as ``bottleneck``.
- ``timing``: ``positions`` (.npy), ``room`` [x0, x1, z0, z1], ``target`` [x, z], ``dt``, ``model``, ``agent``,
  ``warmup``, ``steps`` -> ``ms_per_step`` (list), ``rss_bytes`` (resident set growth from before the
  simulation to after the steps), ``n``.
"""
from __future__ import annotations

import json
import os
import sys
import time


def rss_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def _rect(x0, x1, z0, z1):
    return [(x0, z0), (x1, z0), (x1, z1), (x0, z1)]


def bottleneck(job: dict) -> dict:
    import jupedsim as jps
    import numpy as np
    import shapely

    pos = np.load(job["positions"])
    x0, x1, z0, z1 = job["room"]
    w0, w1, hw = job["door"]
    ox1, oz0, oz1 = job["outside"]
    area = shapely.union_all([shapely.Polygon(_rect(x0, w0, z0, z1)), shapely.Polygon(_rect(w0 - 1e-9, w1 + 1e-9, -hw, hw)),
                              shapely.Polygon(_rect(w1, ox1, oz0, oz1))])
    sim = jps.Simulation(model=jps.CollisionFreeSpeedModel(**job["model"]), geometry=area, dt=job["dt"])
    wx, wz, wd = job["waypoint"]
    journeys = []
    for e in job["exits"]:
        wp = sim.add_waypoint_stage((wx, wz), wd)
        ex = sim.add_exit_stage(_rect(*e))
        jd = jps.JourneyDescription([wp, ex])
        jd.set_transition_for_stage(wp, jps.Transition.create_fixed_transition(ex))
        journeys.append((sim.add_journey(jd), wp))
    return _evacuate(sim, jps, pos, journeys, job)


def bottleneck_scene(job: dict) -> dict:
    """A bottleneck scene's run (bench_avoidance.scene_bottleneck_peer builds the job from the scene file)."""
    import jupedsim as jps
    import numpy as np
    import shapely

    pos = np.load(job["positions"])
    walls = [shapely.Polygon(p) for p in job["polygons"]] + [shapely.Point(x, z).buffer(r, 32)
                                                             for x, z, r in job["circles"]]
    pts = [tuple(p) for p in pos] + [tuple(q) for path in job["paths"] for q in path]
    pts += [c for w in walls for c in w.exterior.coords]
    xs, zs = [p[0] for p in pts], [p[1] for p in pts]
    box = shapely.box(min(xs) - 2.0, min(zs) - 2.0, max(xs) + 2.0, max(zs) + 2.0)
    area = box.difference(shapely.union_all(walls)) if walls else box
    if area.geom_type == "MultiPolygon":  # the part the agents are in
        area = max(area.geoms, key=lambda g: sum(g.contains(shapely.Point(p)) for p in pos))
    sim = jps.Simulation(model=jps.CollisionFreeSpeedModel(**job["model"]), geometry=area, dt=job["dt"])
    journeys = []
    for path in job["paths"]:
        *via, (ex, ez) = path
        stages = [sim.add_waypoint_stage((float(x), float(z)), job["arrive_radius"]) for x, z in via]
        stages.append(sim.add_exit_stage(_rect(ex - 1.0, ex + 1.0, ez - 1.0, ez + 1.0)))
        jd = jps.JourneyDescription(stages)
        for a, b in zip(stages, stages[1:]):
            jd.set_transition_for_stage(a, jps.Transition.create_fixed_transition(b))
        journeys.append((sim.add_journey(jd), stages[0]))
    return _evacuate(sim, jps, pos, journeys, job)


def _evacuate(sim, jps, pos, journeys, job) -> dict:
    import numpy as np
    from scipy.spatial import cKDTree

    ids = []
    for i, (x, z) in enumerate(pos):
        jid, first = journeys[i % len(journeys)]
        ids.append(sim.add_agent(jps.CollisionFreeSpeedModelAgentParameters(
            position=(float(x), float(z)), journey_id=jid, stage_id=first, **job["agent"])))
    index = {a: i for i, a in enumerate(ids)}
    crossing = [None] * len(ids)
    line_x, max_steps = float(job["line_x"]), int(round(job["max_time"] / job["dt"]))
    min_d = float("inf")
    t0 = time.perf_counter()
    steps = 0
    while sim.agent_count() > 0 and steps < max_steps and any(c is None for c in crossing):
        sim.iterate()
        steps += 1
        t = steps * job["dt"]
        xy = []
        for a in sim.agents():
            x, z = a.position
            xy.append((x, z))
            i = index[a.id]
            if crossing[i] is None and x > line_x:
                crossing[i] = t
        if steps % 10 == 0 and len(xy) > 1:
            p = np.asarray(xy)
            d, _ = cKDTree(p).query(p, k=2)
            min_d = min(min_d, float(d[:, 1].min()))
    return {"crossing_times": crossing, "steps": steps, "min_distance": min_d if min_d < float("inf") else None,
            "wall_seconds": time.perf_counter() - t0}


def timing(job: dict) -> dict:
    import jupedsim as jps
    import numpy as np

    pos = np.load(job["positions"])
    x0, x1, z0, z1 = job["room"]
    before = rss_bytes()
    sim = jps.Simulation(model=jps.CollisionFreeSpeedModel(**job["model"]), geometry=_rect(x0, x1, z0, z1),
                         dt=job["dt"])
    tx, tz = job["target"]
    wp = sim.add_waypoint_stage((tx, tz), 0.5)
    jid = sim.add_journey(jps.JourneyDescription([wp]))
    for x, z in pos:
        sim.add_agent(jps.CollisionFreeSpeedModelAgentParameters(position=(float(x), float(z)), journey_id=jid,
                                                                 stage_id=wp, **job["agent"]))
    for _ in range(int(job["warmup"])):
        sim.iterate()
    ms = []
    for _ in range(int(job["steps"])):
        t = time.perf_counter()
        sim.iterate()
        ms.append((time.perf_counter() - t) * 1e3)
    return {"ms_per_step": ms, "rss_bytes": rss_bytes() - before, "n": int(len(pos))}


def main() -> int:
    job = json.load(sys.stdin)
    import jupedsim as jps

    out = {"bottleneck": bottleneck, "bottleneck_scene": bottleneck_scene, "timing": timing}[job["kind"]](job)
    out["jupedsim"] = jps.__version__
    json.dump(out, sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
