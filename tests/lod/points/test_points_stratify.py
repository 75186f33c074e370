"""§3.4.2 stratification: kernel vs reference, coverage, oversampling, time intervals."""
import numpy as np
import pytest

from lod.points.octree import sample_positions_at
from lod.points.sampling import sample_candidates, triangle_vertices
from lod.points.stratify import interval_of, interval_times, stratify, stratify_numpy


def plate(n=8, size=1.0):
    """Flat square plate in the xz plane, (V, 3) positions and (2 n^2, 3) triangles."""
    x = np.linspace(0.0, size, n + 1)
    X, Z = np.meshgrid(x, x, indexing="ij")
    p = np.c_[X.ravel(), np.zeros(X.size), Z.ravel()]
    i = np.arange(n * n)
    a = (i // n) * (n + 1) + (i % n)
    return p, np.r_[np.c_[a, a + 1, a + n + 2], np.c_[a, a + n + 2, a + n + 1]]


def sphere(nu=48, nv=24):
    """UV unit sphere (poles have zero-area triangles)."""
    th = np.linspace(0, np.pi, nv + 1)
    ph = np.linspace(0, 2 * np.pi, nu + 1)[:-1]
    T, P = np.meshgrid(th, ph, indexing="ij")
    p = np.c_[(np.sin(T) * np.cos(P)).ravel(), np.cos(T).ravel(), (np.sin(T) * np.sin(P)).ravel()]
    tris = []
    for i in range(nv):
        for j in range(nu):
            a, b = i * nu + j, i * nu + (j + 1) % nu
            c, d = (i + 1) * nu + j, (i + 1) * nu + (j + 1) % nu
            tris += [(a, c, b), (b, c, d)]
    return p, np.array(tris)


def _pair_coverage_ok(pos, keep, rad):
    """Every candidate is kept or has one kept point within rad at both ends of its interval."""
    for j in range(keep.shape[0]):
        k = np.flatnonzero(keep[j])
        da = np.sqrt(((pos[j][:, None] - pos[j][None, k]) ** 2).sum(-1))
        db = np.sqrt(((pos[j + 1][:, None] - pos[j + 1][None, k]) ** 2).sum(-1))
        if not np.all(((da <= rad) & (db <= rad)).any(1)):
            return False
    return True


def _moving_cloud(rng, n, m):
    p = rng.random((n, 3)) * [1.0, 1.0, 0.05]
    q = p * rng.uniform(0.4, 1.6) + rng.normal(0.0, 0.05, p.shape) + 0.3
    t = interval_times(m)
    return (1 - t)[:, None, None] * p[None] + t[:, None, None] * q[None]


@pytest.mark.parametrize("seed,m", [(0, 1), (1, 3), (2, 4)])
def test_kernel_matches_reference(seed, m):
    rng = np.random.default_rng(seed)
    pos = _moving_cloud(rng, 500, m)
    order = rng.permutation(500)
    got = stratify(pos, 0.15, order)
    assert np.array_equal(got, stratify_numpy(pos, 0.15, order))
    assert _pair_coverage_ok(pos, got, 0.075)
    assert got.sum() < got.size  # something was deleted


def test_kernel_matches_reference_on_coincident_and_collinear_points():
    rng = np.random.default_rng(7)
    line = np.c_[np.linspace(0, 1, 60), np.zeros(60), np.zeros(60)]
    same = np.zeros((40, 3))
    pts = np.concatenate([line, same, line[:20]])  # duplicates too
    pos = np.stack([pts, pts * 0.5])
    order = rng.permutation(pts.shape[0])
    got = stratify(pos, 0.1, order)
    assert np.array_equal(got, stratify_numpy(pos, 0.1, order))
    assert _pair_coverage_ok(pos, got, 0.05)
    assert got[0, 60:100].sum() <= 1  # forty coincident points collapse to at most one


def test_no_cascaded_deletion_on_a_chain():
    """Fig. 5b: points 0.4 r apart in a row; deleting every covered point would leave one."""
    r = 1.0
    x = np.arange(200) * 0.4 * r
    pts = np.c_[x, np.zeros_like(x), np.zeros_like(x)]
    pos = np.stack([pts, pts])
    keep = stratify(pos, r, np.random.default_rng(0).permutation(200))
    assert _pair_coverage_ok(pos, keep, 0.5 * r)
    kx = x[keep[0]]
    # a deleted point has a kept neighbour within r/2, so kept points are at most
    # three steps (1.2 r) apart; cascaded deletion would have left a single point
    assert np.diff(kx).max() <= 1.2 * r + 1e-9 and kx[0] <= 0.4 * r + 1e-9 and kx[-1] >= x[-1] - 0.4 * r - 1e-9


def test_interval_helpers():
    assert np.allclose(interval_times(4), [0, 0.25, 0.5, 0.75, 1])
    assert [interval_of(u, 3) for u in (0.0, 0.33, 0.34, 0.999, 1.0)] == [0, 0, 1, 2, 2]


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="spacing"):
        stratify(np.zeros((2, 3, 3)), 0.0, np.arange(3))
    with pytest.raises(ValueError, match="order"):
        stratify(np.zeros((2, 3, 3)), 1.0, np.arange(2))
    with pytest.raises(ValueError, match="finite"):
        stratify(np.full((2, 3, 3), np.nan), 1.0, np.arange(3))
    assert stratify(np.zeros((3, 0, 3)), 1.0, np.arange(0)).shape == (2, 0)


def _stratified(p0, p1, tri, r, m, seed):
    rng = np.random.default_rng(seed)
    v0, v1 = triangle_vertices(p0, tri), triangle_vertices(p1, tri)
    ct, cb, _ = sample_candidates(v0, v1, r, rng)
    pos = sample_positions_at(v0, v1, ct, cb, interval_times(m))
    return v0, v1, ct, cb, stratify(pos, r, rng.permutation(ct.size))


def test_plate_has_no_holes_at_any_tested_time():
    """Acceptance: every point of a dense reference set lies within r of a kept sample."""
    p0, tri = plate(8)
    p1 = p0 * [1.3, 1.0, 0.8] + [0.2, 0.1, 0.0]  # moves and stretches
    p1[:, 1] += 0.3 * p0[:, 0]  # and tilts
    r, m = 1.0 / 16.0, 3
    v0, v1, ct, cb, keep = _stratified(p0, p1, tri, r, m, seed=11)
    rng = np.random.default_rng(12)
    from lod.points.sampling import sample_positions, sample_triangles

    dt, db = sample_triangles(np.ones(tri.shape[0]), 20_000, rng)
    for j in range(m):
        k = np.flatnonzero(keep[j])
        for u in np.linspace(j / m, (j + 1) / m, 4):
            ref = sample_positions(v0, v1, dt, db, float(u))
            smp = sample_positions(v0, v1, ct[k], cb[k], float(u))
            from scipy.spatial import cKDTree

            d, _ = cKDTree(smp).query(ref)
            assert d.max() <= r, f"hole of {d.max() / r:.2f} r at u = {u:.3f}"


def test_plate_average_oversampling_at_most_2_6():
    """Acceptance (paper §3.4.2: 2.6 on a flat thin plate).

    Oversampling = kept samples / area divided by the density 1 / r^2 the
    splatting renderer must assume (the paper's definition: worst case
    4 / sin 60 = 4.6), i.e. kept * r^2 / area.
    """
    p, tri = plate(8)
    r = 1.0 / 16.0
    vals = []
    for seed in range(3):
        *_, keep = _stratified(p, p, tri, r, 1, seed)
        vals.append(keep.sum() * r * r / 1.0)
    assert np.mean(vals) <= 2.6
    assert min(vals) > 1.2  # the hexagonal covering bound is 1.54 (sanity: not under-sampled)


def test_shrinking_sphere_benefits_from_time_intervals():
    """A sphere shrinking to 1/100 of its area (paper §5.1, Fig. 10).

    The points drawn, averaged over time, relative to one interval. With equal
    intervals and counts proportional to the area at each interval's start
    (uniform scaling makes the start the binding end), the ratio for m
    intervals is sum_j (1 - 0.9 j / m)^2 / m: 0.502 for 4, 0.434 for 8, 0.37
    in the limit (the paper's "about 40%" with fine discretization). The
    issue's "<= 50% with 4 intervals" is therefore out of reach by 0.2%
    with equal intervals; we assert the analytic value within 3% and the
    8-interval figure below 0.45 (chosen intervals: the next test).
    """
    p0, tri = sphere(48, 24)
    p1 = 0.1 * p0
    r = 0.25
    counts = {}
    for m in (1, 4, 8):
        counts[m] = np.mean([_stratified(p0, p1, tri, r, m, seed)[-1].sum(1).mean() for seed in (0, 1)])
    ratio4 = counts[4] / counts[1]
    ratio8 = counts[8] / counts[1]
    model4 = sum((1 - 0.9 * j / 4) ** 2 for j in range(4)) / 4
    assert ratio4 == pytest.approx(model4, rel=0.03)
    assert ratio8 <= 0.45
    assert counts[8] < counts[4] < counts[1]


def test_interval_of_with_bounds():
    b = np.array([0.0, 0.1875, 0.5, 1.0])
    assert [interval_of(u, 3, b) for u in (0.0, 0.18, 0.1875, 0.49, 0.5, 0.99, 1.0, 1.5, -1.0)] == \
        [0, 0, 1, 1, 2, 2, 2, 2, 0]
    assert [interval_of(u, 3, None) for u in (0.0, 0.5, 1.0)] == [0, 1, 2]


def test_chosen_intervals_are_the_cost_optimum_and_equal_for_constant_area():
    from itertools import combinations

    from lod.points.stratify import choose_interval_times, interval_cost_table

    p0, tri = sphere(24, 12)
    v0, v1 = triangle_vertices(p0, tri), triangle_vertices(0.1 * p0, tri)
    G, m = 12, 3
    cost = interval_cost_table(v0, v1, G)
    b = choose_interval_times(v0, v1, m, grid=G, min_gain=0.0)
    assert b[0] == 0.0 and b[-1] == 1.0 and (np.diff(b) > 0).all() and b.shape == (m + 1,)
    got = sum(cost[int(round(b[j] * G)), int(round(b[j + 1] * G))] for j in range(m))
    brute = min(cost[0, a] + cost[a, c] + cost[c, G] for a, c in combinations(range(1, G), 2))
    assert got == pytest.approx(brute, rel=1e-12)
    assert b[1] < 1.0 / 3.0  # shrinking: the large-area start gets the short interval
    # rigid motion (constant area): equal intervals
    moved = triangle_vertices(p0 + [3.0, 1.0, 0.0], tri)
    np.testing.assert_array_equal(choose_interval_times(v0, moved, 4), interval_times(4))
    np.testing.assert_array_equal(choose_interval_times(v0, v1, 1), [0.0, 1.0])
    np.testing.assert_array_equal(choose_interval_times(v0[:0], v1[:0], 3), interval_times(3))


def _interval_ratio(v0, v1, b, r, seed, thinned=True):
    """Points drawn averaged over time with the intervals ``b``, relative to one interval:
    one candidate set (§3.4.1), each interval stratifying it thinned to its own areas
    (``thinned``, as the octree does) or whole."""
    from lod.points.sampling import interval_areas, interval_thinning

    rng = np.random.default_rng(seed)
    ct, cb, A = sample_candidates(v0, v1, r, rng)
    order = rng.permutation(ct.size)
    one = stratify(sample_positions_at(v0, v1, ct, cb, [0.0, 1.0]), r, order).sum()
    eligible = rng.random(ct.size) < interval_thinning(A, interval_areas(v0, v1, b), r)[:, ct] if thinned else None
    keep = stratify(sample_positions_at(v0, v1, ct, cb, b), r, order, eligible=eligible)
    return float((np.diff(b) * keep.sum(1)).sum() / one)


def test_shrinking_sphere_with_chosen_intervals():
    """§5.1 / Fig. 10: a sphere shrinking to 1/100 of its area needs <= 50% of the points
    with 4 time intervals than with 1 (the paper: about 40% with a fine discretization).

    The cost model (points proportional to the area at each interval's binding end) has
    its 4-interval optimum at 0.497 of one interval (equal intervals: 0.502; equal shares
    of the area change: 0.509; of log area: 0.59, both worse), so 50% is reached only
    near the optimum. Stratifying the whole shared candidate set in every interval gives
    0.505: the late, small intervals then stratify a set ~10x denser than their area
    needs and keep ~5% more points from it; thinned to each interval's own candidate
    density (lod.points.sampling.interval_thinning) the measured ratio meets the model.
    """
    from lod.points.stratify import choose_interval_times, interval_cost_table

    p0, tri = sphere(48, 24)
    p1 = 0.1 * p0
    v0, v1 = triangle_vertices(p0, tri), triangle_vertices(p1, tri)
    b = choose_interval_times(v0, v1, 4)
    G = 48
    cost = interval_cost_table(v0, v1, G)
    k = np.rint(b * G).astype(int)
    model = sum(cost[k[j], k[j + 1]] for j in range(4)) / cost[0, G]
    model_eq = sum(cost[12 * j, 12 * (j + 1)] for j in range(4)) / cost[0, G]
    assert model == pytest.approx(0.4966, abs=0.003) and model <= 0.99 * model_eq
    r = 0.125
    thinned = [_interval_ratio(v0, v1, b, r, seed) for seed in (0, 1, 2)]
    whole = [_interval_ratio(v0, v1, b, r, seed, thinned=False) for seed in (0, 1, 2)]
    assert np.mean(thinned) <= 0.50
    assert np.mean(thinned) == pytest.approx(model, rel=0.02)
    assert np.mean(thinned) < np.mean(whole)


def test_eligible_candidates_are_stratified_alone():
    """stratify(eligible=...): interval j keeps only eligible candidates, and equals stratifying
    the eligible subset alone in the same relative order; the rest need no cover."""
    rng = np.random.default_rng(4)
    pos = _moving_cloud(rng, 1500, 3)
    order = rng.permutation(1500)
    el = rng.random((3, 1500)) < [[1.0], [0.5], [0.1]]
    keep = stratify(pos, 0.12, order, eligible=el)
    assert not (keep & ~el).any()
    for j in range(3):
        idx = np.flatnonzero(el[j])
        rank = np.cumsum(el[j]) - 1
        sub = stratify(pos[j:j + 2][:, idx], 0.12, rank[order[el[j][order]]])
        np.testing.assert_array_equal(keep[j, idx], sub[0])
        assert _pair_coverage_ok(pos[j:j + 2][:, idx], keep[j:j + 1, idx], 0.06)
    np.testing.assert_array_equal(stratify(pos, 0.12, order, eligible=np.ones((3, 1500), bool)),
                                  stratify(pos, 0.12, order))
    with pytest.raises(ValueError, match="eligible"):
        stratify(pos, 0.12, order, eligible=el[:2])


def test_interval_thinning_matches_each_intervals_own_draw():
    """Thinning the pair's candidates gives each interval the coupon-collector count of its
    own maximum areas, distributed like them; one interval (or constant areas) keeps all."""
    from lod.points.sampling import candidate_count, interval_areas, interval_thinning, max_area

    p0, tri = sphere(24, 12)
    v0, v1 = triangle_vertices(p0, tri), triangle_vertices(0.1 * p0, tri)
    A, _ = max_area(v0, v1)
    b = np.array([0.0, 0.25, 0.5, 1.0])
    Aj = interval_areas(v0, v1, b)
    assert np.all(Aj <= A * (1 + 1e-12)) and np.allclose(Aj[0], A)
    p = interval_thinning(A, Aj, 0.1)
    N = candidate_count(A.sum(), 0.1)
    for j in range(3):
        expect = candidate_count(Aj[j].sum(), 0.1)
        got = float((N * A / A.sum() * p[j]).sum())  # expected thinned count
        assert got == pytest.approx(expect, rel=1e-6)
    big = A > 1e-9 * A.max()  # (the pole rows hold zero-area triangles up to rounding)
    assert p[0][big].min() > 0.99 and p[2][big].max() < 0.3 and np.all(p[:, A == 0] == 0)
    moved = triangle_vertices(p0 + 1.0, tri)
    pm = interval_thinning(max_area(v0, moved)[0], interval_areas(v0, moved, b), 0.1)
    assert pm[:, big].min() > 0.95  # rigid motion: the same areas, only the log factor of the counts differs
    assert np.array_equal(interval_thinning(np.zeros(3), np.zeros((2, 3)), 0.1), np.zeros((2, 3)))


def test_threaded_intervals_equal_serial():
    rng = np.random.default_rng(9)
    p = rng.uniform(0, 1, (3000, 3))
    pos = np.stack([p + t * rng.normal(scale=0.05, size=p.shape) for t in range(4)])
    order = rng.permutation(3000)
    a = stratify(pos, 0.2, order, threads=1)
    b = stratify(pos, 0.2, order, threads=3)
    np.testing.assert_array_equal(a, b)


def test_jobs_in_parallel_equal_serial_and_single_calls(monkeypatch):
    """stratify_async: several candidate sets, (set, interval) items on 1 or 2 threads, array or
    lazy per-interval positions: bit-identical to one stratify call per set (and to the reference)."""
    from lod.points import stratify as points_stratify

    monkeypatch.setattr(points_stratify, "PARALLEL_MIN_CANDIDATES", 0)
    rng = np.random.default_rng(21)
    jobs, lazy = [], []
    for n, m, r in ((1500, 3, 0.12), (40, 2, 0.3), (0, 3, 0.1), (900, 1, 0.2), (2500, 4, 0.08)):
        pos = _moving_cloud(rng, n, m)
        order = rng.permutation(n)
        jobs.append((pos, r, order))
        lazy.append(((m, lambda j, pos=pos: pos[j:j + 2]), r, order))
    single = [stratify(p, r, o, threads=1) for p, r, o in jobs]
    for threads in (1, 2):
        for js in (jobs, lazy):
            done = {}
            pend = [points_stratify.stratify_async(p, r, o, threads=threads,
                                                   on_done=lambda k, b=b: done.setdefault(b, k.copy()))
                    for b, (p, r, o) in enumerate(js)]
            got = [h.result() for h in pend]
            assert all(np.array_equal(a, b) and a.shape == b.shape for a, b in zip(got, single))
            assert sorted(done) == list(range(len(jobs)))  # once per job, the empty one too, when complete
            assert all(np.array_equal(done[b], single[b]) for b in done)
        pend = [points_stratify.stratify_async(p, r, o, threads=threads) for p, r, o in lazy]
        assert all(np.array_equal(h.result(), b) for h, b in zip(pend, single))
    p, r, o = jobs[1]
    assert np.array_equal(single[1], stratify_numpy(p, r, o))
    with pytest.raises(ValueError, match="finite"):
        points_stratify.stratify_async((1, lambda j: np.full((2, 40, 3), np.nan)), 0.3, jobs[1][2]).result()
