"""The frame-major form of a recording (issue 47, item 2; ``sim.replay.frames``): the slices hold every row once,
in frame then person order, with the person's next row; a cached entry streams the same rows from its files as the
recording in memory gives; a broken entry is parsed again; the replay of a cached recording is the in-memory one."""
import numpy as np
import pytest

from sim.replay import from_columns
from sim.replay.frames import FrameTable, Stream


def gappy(seed=5, people=30, span=120):
    """People with gaps in their frames, different spans, some with one row, far from the origin."""
    rng = np.random.default_rng(seed)
    ids, frames, xy = [], [], []
    for p in range(people):
        k = 1 if p % 7 == 0 else int(rng.integers(2, 40))
        f = np.sort(rng.choice(np.arange(span), size=k, replace=False)).astype(np.float64)
        ids += [p * 3 + 1] * k
        frames += f.tolist()
        xy += (rng.normal(size=(k, 2)) + [4.0e5, -2.5e5]).tolist()
    return from_columns(ids, frames, xy, 10.0, "gappy.txt")


def test_slices_hold_every_row_once_in_frame_then_person_order_with_the_next_row():
    rec = gappy()
    t = rec.frame_table()
    assert t.rows == rec.rows and t.slices == np.unique(rec.frames).shape[0]
    assert (np.diff(t.values) > 0).all()
    seen = set()
    for j in range(t.slices):
        person, seg = t.slice(j)
        assert (np.diff(person) > 0).all()  # a person once per slice, in order
        for p, row in zip(person.tolist(), seg):
            lo, hi = rec.start[p], rec.start[p + 1]
            r = lo + int(np.flatnonzero(rec.frames[lo:hi] == t.values[j])[0])
            nxt = min(r + 1, hi - 1)
            np.testing.assert_array_equal(row, [*rec.xy[r], rec.frames[nxt], *rec.xy[nxt]])
            seen.add(r)
    assert len(seen) == rec.rows


@pytest.mark.parametrize("keep_bytes, ahead_rows", [(128 << 20, 1 << 15), (0, 1 << 15), (600, 1), (2000, 3)])
def test_a_cached_entry_streams_what_the_recording_in_memory_gives(tmp_path, monkeypatch, keep_bytes, ahead_rows):
    """Whatever the table keeps and reads ahead (everything; nothing; a slice or two, a row or three at a time)."""
    import sim.replay.frames as frames
    from sim.replay import cache
    from sim.replay.recording import cached

    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(frames, "KEEP_BYTES", keep_bytes)
    monkeypatch.setattr(frames, "AHEAD_MIN_ROWS", ahead_rows)
    rec = gappy()
    cache.save("k1", rec)
    again = cached("k1", "gappy.txt", "txt")
    assert again is not None and again.table.person is None  # rows left in the files
    np.testing.assert_array_equal(again.ends, rec.ends)
    for j in range(rec.frame_table().slices):
        for a, b in zip(again.table.slice(j), rec.frame_table().slice(j)):
            np.testing.assert_array_equal(a, b)
    persons = np.arange(rec.persons)
    s1 = Stream(rec.frame_table(), rec.first, rec.last, rec.first_xy)
    s2 = Stream(again.table, again.first, again.last, again.first_xy)
    for f in list(np.arange(-3.0, 125.0, 0.7)) + [60.0, -1.0, 130.0] + list(np.arange(20.0, 50.0, 0.3)):
        got = s2.rows(persons, f, 4.0, 10.0)
        np.testing.assert_array_equal(got, s1.rows(persons, f, 4.0, 10.0))
        assert np.isfinite(got).all()
        np.testing.assert_allclose(got[:, :2], rec.at(persons, f), rtol=0, atol=1e-9)


@pytest.mark.parametrize("damage", ["truncate", "remove", "shape"])
def test_a_broken_frame_table_makes_the_entry_unreadable(tmp_path, monkeypatch, damage):
    from sim.replay import cache
    from sim.replay.frames import FILES

    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path / "cache"))
    cache.save("k2", gappy())
    seg = cache.cache_dir() / "k2" / FILES["seg"]
    if damage == "truncate":
        seg.write_bytes(seg.read_bytes()[:-40])
    elif damage == "remove":
        seg.unlink()
    else:
        np.save(seg, np.zeros((3, 5)))
    assert cache.load("k2") is None


def test_a_table_needs_its_rows():
    with pytest.raises(ValueError):
        FrameTable(np.zeros(1), np.array([0, 1]))


def test_an_opened_table_holds_at_most_what_it_may_keep(tmp_path, monkeypatch):
    """KEEP_BYTES bounds the slices kept and the one read ahead; passed slices are dropped."""
    import sim.replay.frames as frames
    from sim.replay import cache
    from sim.replay.recording import cached

    monkeypatch.setenv("CROWD_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(frames, "KEEP_BYTES", 3 * 30 * frames.ROW_BYTES)
    monkeypatch.setattr(frames, "AHEAD_MIN_ROWS", 4)
    cache.save("k3", gappy(people=30))
    rec = cached("k3", "gappy.txt", "txt")
    s = Stream(rec.table, rec.first, rec.last, rec.first_xy)
    for f in np.arange(0.0, 120.0, 0.25):
        s.rows(np.arange(rec.persons), f, 2.0, 10.0)
        assert rec.table._kept_bytes() <= frames.KEEP_BYTES
        lowest = min(c.applied for c in s.cursors)
        assert all(j >= lowest for j in rec.table._kept)
