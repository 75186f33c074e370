"""Poses that follow the clip (lod/points/poses.py): the baked poses of every clip stay within the pose-error
bound of the skinned animation, sampled densely in time; a loop jump is not pose error; long varied clips get
more poses than short ones; the search's vertex subset is verified on every vertex; mode points and auto use it."""
import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "fixtures"))

from lod.points import poses as lp  # noqa: E402
from sim.clip import Channel, Clip  # noqa: E402
from sim.procedural import humanoid, quadruped, varied_clip  # noqa: E402

SHARED = Path(__file__).resolve().parents[4] / "shared" / "assets"


def turn_clip(ch, duration: float = 1.0) -> Clip:
    """The root turning 0 -> 90 degrees about +Y over the clip, looping: the pose at the end is not the pose at
    the start (a jump at the loop point)."""
    times = np.array([0.0, duration])
    q = np.array([[0.0, 0.0, 0.0, 1.0], [0.0, np.sin(np.pi / 4), 0.0, np.cos(np.pi / 4)]])
    return Clip("turn", duration, [Channel(0, "rotation", times, q)], loop=True)


def still_clip(duration: float = 2.0) -> Clip:
    return Clip("still", duration, [], loop=True)


@pytest.fixture(scope="module")
def walker():
    return humanoid(1000, seed=3)


def check_within(ch, clip, cp, bound):
    """The chosen poses' error, measured again on every vertex at the dense samples, is within the bound."""
    err, _ = lp.clip_error(ch, clip, cp.times)
    assert err <= bound * (1 + 1e-9) + 1e-12, (clip.name, err, bound, len(cp.times))
    assert cp.error == pytest.approx(err, rel=1e-5, abs=1e-9)
    assert cp.times[0] == 0.0 and np.all(np.diff(cp.times) > 0) and cp.times[-1] <= clip.duration


@pytest.mark.parametrize("make", [lambda: humanoid(1000, seed=3), lambda: quadruped(1200, seed=2)],
                         ids=["humanoid", "quadruped"])
def test_every_clip_within_the_bound_with_default_settings(make):
    from lod.points.config import POINTS_MAX_POSES, POINTS_POSE_ERROR

    ch = make()
    bound = POINTS_POSE_ERROR * lp.character_extent(ch)
    chosen = lp.clip_poses(ch, 0, POINTS_POSE_ERROR, POINTS_MAX_POSES)
    assert set(chosen) == set(ch.clips)
    for name, cp in chosen.items():
        assert not cp.capped and cp.bound == pytest.approx(bound)
        check_within(ch, ch.clip(name), cp, bound)
        # evenly spaced poses of the same count do worse or equal: the times follow the motion
        even = lp.uniform_poses(ch, ch.clip(name), len(cp.times))
        assert even.error >= 0.5 * cp.error


def clips_within_the_bound(paths) -> int:
    """Load each glTF file; every clip of every skinned one, with the default pose settings, stays within the
    bound (and is not capped). Returns the clips checked."""
    from lod.points.config import POINTS_MAX_POSES, POINTS_POSE_ERROR
    from sim.gltf.load import load_gltf

    seen = 0
    for path in paths:
        ch = load_gltf(path)
        if ch.kind != "skinned":
            continue
        bound = POINTS_POSE_ERROR * lp.character_extent(ch)
        for name, cp in lp.clip_poses(ch, 0, POINTS_POSE_ERROR, POINTS_MAX_POSES).items():
            assert not cp.capped, (path.name, name)
            check_within(ch, ch.clip(name), cp, bound)
            seen += 1
    return seen


def test_generated_corpus_every_clip_within_the_bound(tmp_path):
    """The generated corpus (scripts/corpus_models.py: mixed rig, statue, 100-deep chain, 64 primitives, 0.1 s
    and 60 s clips, skin + morph targets, humanoid): with the defaults every clip's poses stay within the bound."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "scripts"))
    from corpus_models import write_models

    assert clips_within_the_bound([p for p in write_models(tmp_path) if not p.name.startswith("refused_")]) >= 8


@pytest.mark.skipif(not SHARED.is_dir(), reason=f"no shared assets at {SHARED}")
def test_real_models_every_clip_within_the_bound():
    assert clips_within_the_bound(sorted(SHARED.glob("*.glb"))) >= 4


def test_a_clip_that_holds_still_gets_two_poses(walker):
    ch = dataclasses.replace(walker, clips={"still": still_clip()})
    cp = lp.choose_poses(ch, ch.clip("still"), 0.01)
    assert len(cp.times) == 2 and cp.error < 1e-9


def test_long_varied_clip_gets_poses_where_it_moves(walker):
    long = varied_clip(walker, 30.0, seed=5, name="dance")
    ch = dataclasses.replace(walker, clips={"walk": walker.clip("walk"), "dance": long})
    bound = 0.02 * lp.character_extent(ch)
    short = lp.choose_poses(ch, ch.clip("walk"), bound)
    cp = lp.choose_poses(ch, long, bound, max_poses=4096)
    check_within(ch, long, cp, bound)
    check_within(ch, ch.clip("walk"), short, bound)
    # the 30 s clip needs far more poses than the 1.1 s walk, and about as many per second of motion
    assert len(cp.times) > 10 * len(short.times)
    per_s_long, per_s_short = len(cp.times) / long.duration, len(short.times) / ch.clip("walk").duration
    assert 0.3 * per_s_short < per_s_long < 3.0 * per_s_short
    # the fixed 9 poses of before leave this clip tens of percent off
    assert lp.uniform_poses(ch, long, 9).error > 10 * bound


def test_the_cap_stops_refinement_and_says_so(walker):
    long = varied_clip(walker, 10.0, seed=1, name="dance")
    ch = dataclasses.replace(walker, clips={"dance": long})
    bound = 0.01 * lp.character_extent(ch)
    cp = lp.choose_poses(ch, long, bound, max_poses=8)
    assert len(cp.times) == 8 and cp.capped and cp.error > bound


def test_the_loop_jump_is_not_pose_error(walker):
    """A root turning 90 degrees and jumping back at the loop point: the chosen poses bound the error over the
    clip; the jump itself (half a metre of vertex travel) does not force poses, and many evenly spaced poses
    converge to zero error rather than to half the jump."""
    clip = turn_clip(walker)
    ch = dataclasses.replace(walker, clips={"turn": clip})
    ext = lp.character_extent(ch)
    p0 = np.asarray(ch.mesh.positions)
    jump = float(np.linalg.norm(p0[:, [0, 2]], axis=1).max()) * np.sqrt(2.0)  # chord of a 90 degree turn
    assert jump > 0.1
    cp = lp.choose_poses(ch, clip, 0.02 * ext)
    check_within(ch, clip, cp, 0.02 * ext)
    assert len(cp.times) <= 8
    assert cp.times[-1] == pytest.approx(clip.duration * (1 - 1 / 30.0))  # a key right before the jump
    fine = [lp.uniform_poses(ch, clip, n).error for n in (8, 32, 64)]
    assert fine[0] > fine[1] > fine[2] and fine[2] < 0.01 * jump


def test_search_subset_is_verified_on_every_vertex(walker, monkeypatch):
    """With the search restricted to a few vertices, the vertices it did not see are still within the bound."""
    monkeypatch.setattr(lp, "SEARCH_VERTICES", 16)
    ch = walker
    bound = 0.01 * lp.character_extent(ch)
    cp = lp.choose_poses(ch, ch.clip("run"), bound)
    check_within(ch, ch.clip("run"), cp, bound)


def test_uniform_override_and_one_pose(walker):
    cp = lp.uniform_poses(walker, walker.clip("walk"), 9)
    assert len(cp.times) == 9 and np.allclose(np.diff(cp.times), walker.clip("walk").duration / 9)
    assert cp.bound == np.inf
    one = lp.uniform_poses(walker, walker.clip("walk"), 1)
    assert one.times.tolist() == [0.0] and one.error == 0.0


def test_points_mode_bakes_the_chosen_poses(walker, tmp_path):
    from lod.points import mode as pm
    from lod.points.rep import HierarchyCache

    ch = dataclasses.replace(walker, clips={"walk": walker.clip("walk")})
    cache = HierarchyCache(tmp_path / "c")
    reps, _ = pm.build([ch], ["w"], [30], {"intervals": 1, "animation": "baked"}, cache=cache, progress=False)
    rep = reps[0]
    cp = rep.poses["walk"]
    assert len(cp.times) >= 2 and cp.error <= cp.bound
    assert rep.keyframed.n_parts == len(cp.times)  # a looping clip: one segment per pose
    fixed, _ = pm.build([ch], ["w"], [30], {"keyframes": 4, "intervals": 1, "animation": "baked"}, cache=cache,
                        progress=False)
    assert len(fixed[0].poses["walk"].times) == 4 and fixed[0].keyframed.n_parts == 4


def test_auto_prices_points_with_the_pose_error_of_its_poses(walker):
    from lod.auto import candidates as ac
    from lod.auto import build as ab
    from lod.auto import mode as am

    ch = dataclasses.replace(walker, clips={"walk": walker.clip("walk")})
    _, sel = ab.build([ch], ["w"], [30], {"candidates": "triangles,points"}, progress=False, cache=False,
                      points_params={"animation": "baked"})
    pts = next(c for c in sel.candidates if c.name == "points")
    dev = ac.keyframe_deviation(ch, 0)
    assert pts.deviation[0] == pytest.approx(dev)
    assert 0.0 < dev <= 0.02 * lp.character_extent(ch)
    # samples that follow the animation (the default) depart from it by nothing: the splat gets the whole bound
    _, sel = ab.build([ch], ["w"], [30], {"candidates": "triangles,points"}, progress=False, cache=False)
    pts = next(c for c in sel.candidates if c.name == "points")
    assert pts.deviation[0] == 0.0 and pts.splat_size(2.0) == 2


def test_pose_error_includes_morph_targets(monkeypatch):
    """A skinned character with animated morph targets: the pose error is measured on skin ∘ morph (what mode
    points bakes), so the chosen poses bound it, on the search subset and on every vertex."""
    from tiny_characters import tiny_morphed

    from sim.skinning import skin, skin_morph

    ch = tiny_morphed()
    clip = ch.clip("bend")
    S = lp.sample_times(clip)
    mats = clip.skinning_matrices(ch.skeleton, S)
    w = clip.morph_weights(ch.mesh.morph, S)
    moved = max(float(np.abs(skin_morph(ch.mesh, mats[k], w[k])[0] - skin(ch.mesh, mats[k])[0]).max())
                for k in range(S.size))
    assert moved > 0.05  # the morphs move the mesh beyond the skinning alone
    bound = 0.01 * lp.character_extent(ch)
    for sub in (lp.SEARCH_VERTICES, 8):  # all vertices in the search, then a subset verified on every vertex
        monkeypatch.setattr(lp, "SEARCH_VERTICES", sub)
        cp = lp.choose_poses(ch, clip, bound)
        assert cp.error <= bound
        # the reference: skin ∘ morph at every sample against the interpolated chosen poses
        keys = [int(np.argmin(np.abs(S - t))) for t in cp.times]
        P = [skin_morph(ch.mesh, mats[k], w[k])[0] for k in range(S.size)]
        ends = keys[1:] + [S.size]
        worst = 0.0
        for i, j in zip(keys, ends):
            t1 = S[j] if j < S.size else clip.duration + S[0]
            for k in range(i + 1, j):
                u = (S[k] - S[i]) / (t1 - S[i])
                worst = max(worst, float(np.linalg.norm((1 - u) * P[i] + u * P[j % S.size] - P[k], axis=1).max()))
        assert worst <= bound * (1 + 1e-6)


def test_memory_estimate_counts_the_poses(walker, tmp_path):
    """The memory guard's estimate of mode points grows with the poses a clip needs and is within a factor
    of two of the hierarchies actually built."""
    from lod.points import mode as pm
    from lod.points.rep import HierarchyCache

    ch = dataclasses.replace(walker, clips={"walk": walker.clip("walk")})
    baked = {"animation": "baked"}
    reps, _ = pm.build([ch], ["w"], [30], baked, cache=HierarchyCache(tmp_path / "c"), progress=False)
    est = pm.memory_estimate([ch], baked)
    assert 0.5 * reps[0].nbytes <= est <= 2.0 * reps[0].nbytes, (est, reps[0].nbytes)
    long = dataclasses.replace(walker, clips={"dance": varied_clip(walker, 20.0, seed=2, name="dance")})
    assert pm.memory_estimate([long], baked) > 10 * est
    assert pm.memory_estimate([long], {"keyframes": 9, **baked}) < 2 * est
    # the default: samples that follow the animation, whatever the clip's length
    reps, _ = pm.build([ch], ["w"], [30], {}, cache=HierarchyCache(tmp_path / "c"), progress=False)
    est = pm.memory_estimate([ch], {})
    assert 0.5 * reps[0].nbytes <= est <= 2.0 * reps[0].nbytes, (est, reps[0].nbytes)
    assert pm.memory_estimate([long], {}) == est
