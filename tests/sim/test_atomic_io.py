"""sim.atomic_io: a file appears complete or not at all."""
import os

import pytest

from sim.atomic_io import atomic_open, write_atomic


def test_write_atomic_creates_parents_and_replaces(tmp_path):
    p = tmp_path / "a" / "b" / "x.bin"
    write_atomic(p, b"one")
    assert p.read_bytes() == b"one"
    write_atomic(p, "two")
    assert p.read_text() == "two"
    assert [q.name for q in p.parent.iterdir()] == ["x.bin"]  # no temporary left behind
    assert oct(p.stat().st_mode & 0o777) != oct(0o600)  # not mkstemp's private mode


def test_failed_write_keeps_previous_file_and_leaves_no_temporary(tmp_path):
    p = tmp_path / "x.txt"
    write_atomic(p, "old")
    with pytest.raises(RuntimeError):
        with atomic_open(p, "w") as f:
            f.write("half a fi")
            raise RuntimeError("disk full")
    assert p.read_text() == "old"
    assert sorted(os.listdir(tmp_path)) == ["x.txt"]


def test_failed_first_write_leaves_nothing(tmp_path):
    p = tmp_path / "new.txt"
    with pytest.raises(KeyboardInterrupt):
        with atomic_open(p, "wb") as f:
            f.write(b"abc")
            raise KeyboardInterrupt
    assert os.listdir(tmp_path) == []


def test_bad_mode_is_refused(tmp_path):
    with pytest.raises(ValueError, match="mode"):
        with atomic_open(tmp_path / "x", "a"):
            pass
