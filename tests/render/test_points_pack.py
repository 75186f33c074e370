"""The point drawer's per-frame packing in numba (render/points/pack.py) against the numpy functions it stands
for: folded instance rows (render.points.draw.fold_box), colour words (render.tint.batch_words), job tables with
their prefix (render.points.draw.job_table); and the fused dot product against numpy's matrix product."""
from types import SimpleNamespace

import numpy as np
import pytest

from render.points import draw as rp
from render.points import pack
from render import tint


def _batches(rng):
    out = []
    for i, (k, dt) in enumerate(((5000, np.float32), (700, np.float64), (1, np.float32))):
        d = rng.standard_normal((k, 16)).astype(dt) * np.array([1] * 12 + [0.5] * 4) * (10.0 ** (i + 1))
        j = np.column_stack([rng.integers(0, k, 3 * k), rng.integers(0, 5000, 3 * k), rng.integers(0, 4, 3 * k)])
        j = j[np.argsort(j[:, 0], kind="stable")]
        out.append(SimpleNamespace(rep="points:a" if i != 1 else "points:b", part=i % 2, n_instances=k,
                                   instance_ids=rng.integers(-3, 9000, k).astype(np.int32), instance_data=d,
                                   tint=None if i else (0.2, 0.4, 0.9, 0.5), point_jobs=j, tri_jobs=j[:7]))
    out.append(SimpleNamespace(rep="static:terrain", part=0, n_instances=3, instance_ids=np.array([-1, 2, 5], np.int32),
                               instance_data=np.ones((3, 16), np.float32), tint=None, point_jobs=np.zeros((0, 3)),
                               tri_jobs=np.zeros((0, 3))))
    return out


def test_fold_rows_equal_fold_box():
    rng = np.random.default_rng(3)
    bs = _batches(rng)
    boxes = [(rng.uniform(-2, 2, 3), float(rng.uniform(0.5, 3.0))) for _ in bs]
    got, finite = pack.fold_rows(bs, boxes)
    ref = np.concatenate([rp.fold_box(b.instance_data, *bx) for b, bx in zip(bs, boxes)])
    assert finite and got.dtype == np.float32
    np.testing.assert_array_equal(got, ref)
    bs[1].instance_data[3, 7] = np.inf
    assert not pack.fold_rows(bs, boxes)[1]


def test_fused_dot_rounds_as_numpys_product():
    rng = np.random.default_rng(4)
    m = rng.standard_normal((20000, 3)).astype(np.float32).astype(np.float64)
    lo = rng.standard_normal(3)
    ref = m @ lo
    got = np.array([pack._dot3(*r, *lo) for r in m[:2000]])
    np.testing.assert_array_equal(got, ref[:2000])


def test_batch_words_and_job_tables_equal_the_reference():
    rng = np.random.default_rng(5)
    bs = _batches(rng)
    table = rng.integers(0, 2 ** 32, 6000, dtype=np.uint64).astype(np.uint32)
    for t in (table, None):
        np.testing.assert_array_equal(pack.batch_words(bs, t), tint.batch_words(bs, t))
    offs, rows = {}, 0
    for b in bs:
        offs[id(b)] = rows
        rows += b.n_instances
    bases = np.array([0, 123456], np.int64)
    for key in ("points:a", "points:b", "points:none"):
        for which in ("point_jobs", "tri_jobs"):
            got = pack.job_table(bs, key, bases, which, offs)
            ref = rp.job_table(bs, key, bases, which, offs)
            assert got.dtype == np.uint32
            np.testing.assert_array_equal(got, ref)
    big = SimpleNamespace(rep="points:a", part=0, n_instances=1, point_jobs=np.array([[0, 0, 2 ** 31]] * 2))
    with pytest.raises(ValueError, match="2\\*\\*32"):
        pack.job_table([big], "points:a", bases, "point_jobs", {id(big): 0})
