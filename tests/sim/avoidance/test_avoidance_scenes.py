"""The pedestrian scenes with avoidance: no two bodies overlap (beyond 1 % of r_i + r_j) and no agent
enters an obstacle at any step, for cfsm and orca; the crossing scene ends (nobody deadlocked).

Runtimes are kept modest: fewer agents where a scene has a random placement (a smaller variant), the
characters' triangle counts lowered (the simulation never reads them), a few seconds of simulated time;
exhibition also runs in full (1,000 visitors, every effect as shipped) for 5 s."""
import numpy as np
import pytest

from avoid_testutil import run_checked, world_from_scene

MODELS = ("cfsm", "orca")


def _few_triangles(doc):
    for c in doc["characters"]:
        if "generator" in c:
            c["triangles"] = 1000


@pytest.mark.parametrize("model", MODELS)
def test_corridor_dense_no_overlap(model):
    # 432 agents = 3 per m^2 of the start area (the scene's density sweep key is the count)
    sc, w = world_from_scene("corridor", model=model, count=432, scene_edit=_few_triangles)
    run_checked(w, 100, sc.dt)
    # unidirectional flow keeps moving: mean speed well above 0 after 5 s
    assert np.hypot(w.state.velocity[:, 0], w.state.velocity[:, 2]).mean() > 0.2


@pytest.mark.parametrize("model", MODELS)
def test_bottleneck_no_overlap_and_people_get_out(model):
    sc, w = world_from_scene("bottleneck", model=model, scene_edit=_few_triangles)
    run_checked(w, 400, sc.dt)  # 20 s
    assert (w.state.position[:, 0] > 0.4).sum() >= 10  # the door lets people through


@pytest.mark.parametrize("model, bound", [("cfsm", 40.0), ("orca", 60.0)])
def test_crossing_everyone_arrives_within_the_stated_bound(model, bound):
    """Bounds stated in scenes/crossing.toml: every agent is within 0.5 m of its antipode within 40 s
    (cfsm; measured 29.8 s) or 60 s (orca; measured 41.5 s); the free walk takes 16 m / 1.3 m/s = 12.3 s."""
    sc, w = world_from_scene("crossing", model=model, scene_edit=_few_triangles)
    g = w.resources["goals"]
    target = g.waypoints[g.pstart[g.path + 1] - 1]
    arrived_at = np.full(w.state.n, np.inf)
    for k in range(0, int(round(bound / sc.dt)), 50):
        run_checked(w, 50, sc.dt)
        d = np.hypot(w.state.position[:, 0] - target[:, 0], w.state.position[:, 2] - target[:, 1])
        arrived_at = np.where((d < 0.5) & np.isinf(arrived_at), w.time, arrived_at)
        if np.isfinite(arrived_at).all():
            break
    assert np.isfinite(arrived_at).all(), f"{np.isinf(arrived_at).sum()} agents not arrived within {bound:g} s"


@pytest.mark.parametrize("model", MODELS)
def test_exhibition_small_variant_no_overlap(model):
    sc, w = world_from_scene("exhibition", model=model, count=250, scene_edit=_few_triangles)
    run_checked(w, 150, sc.dt)


def test_exhibition_full_scene_five_seconds():
    sc, w = world_from_scene("exhibition", scene_edit=_few_triangles)
    assert w.state.n == 1000 and "avoidance" in w.effects and "boids" in w.effects
    run_checked(w, 150, sc.dt)
    # the figure of the issue: nobody has another visitor's centre within 0.7 m
    from scipy.spatial import cKDTree

    d, _ = cKDTree(w.state.position[:, [0, 2]]).query(w.state.position[:, [0, 2]], k=2)
    assert (d[:, 1] < 0.7 * 0.99).mean() <= 0.001


def test_office_no_overlap():
    sc, w = world_from_scene("office", scene_edit=_few_triangles)
    run_checked(w, 100, sc.dt)
