"""crowd.output: a run's directory appears complete or not at all."""
import os

import pytest

from crowd.output import atomic_dir, temp_sibling, write_atomic, write_json


def test_atomic_dir_appears_only_on_success(tmp_path):
    final = tmp_path / "run"
    with atomic_dir(final) as tmp:
        assert tmp == temp_sibling(final) and tmp.name == f".run.tmp-{os.getpid()}"
        (tmp / "a.txt").write_text("x")
        assert not final.exists()
    assert (final / "a.txt").read_text() == "x"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_atomic_dir_replaces_previous_run(tmp_path):
    final = tmp_path / "run"
    final.mkdir()
    (final / "old.txt").write_text("old")
    with atomic_dir(final) as tmp:
        (tmp / "new.txt").write_text("new")
    assert sorted(p.name for p in final.iterdir()) == ["new.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


@pytest.mark.parametrize("exc", [RuntimeError, KeyboardInterrupt])
def test_atomic_dir_error_leaves_nothing_and_keeps_previous(tmp_path, exc):
    final = tmp_path / "run"
    final.mkdir()
    (final / "old.txt").write_text("old")
    with pytest.raises(exc):
        with atomic_dir(final) as tmp:
            (tmp / "half.txt").write_text("half")
            raise exc()
    assert sorted(p.name for p in final.iterdir()) == ["old.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_atomic_dir_error_without_previous_leaves_nothing(tmp_path):
    with pytest.raises(ValueError):
        with atomic_dir(tmp_path / "sub" / "run"):
            raise ValueError
    assert [p.name for p in (tmp_path / "sub").iterdir()] == []


def test_atomic_dir_refuses_a_file(tmp_path):
    (tmp_path / "run").write_text("not a dir")
    with pytest.raises(FileExistsError):
        with atomic_dir(tmp_path / "run"):
            pass


def test_stale_temp_dir_of_same_pid_is_cleared(tmp_path):
    final = tmp_path / "run"
    stale = temp_sibling(final)
    stale.mkdir()
    (stale / "junk").write_text("j")
    with atomic_dir(final) as tmp:
        assert list(tmp.iterdir()) == []


def test_write_atomic_and_json(tmp_path):
    write_atomic(tmp_path / "a.txt", "hello")
    write_atomic(tmp_path / "a.txt", b"bye")
    assert (tmp_path / "a.txt").read_bytes() == b"bye"
    write_json(tmp_path / "s.json", {"x": 1.5})
    assert (tmp_path / "s.json").read_text().strip().startswith("{")
    with pytest.raises(ValueError):
        write_json(tmp_path / "bad.json", {"x": float("nan")})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "s.json"]


def test_a_killed_runs_temporary_folder_is_removed_by_the_next_run(tmp_path):
    """SIGKILL leaves ``.NAME.tmp-PID`` behind; the next run into the same place removes it (its process is
    gone) but not the folder of a run still in progress, nor unrelated dot-folders."""
    import signal
    import subprocess
    import sys

    final = tmp_path / "run"
    p = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    killed = tmp_path / f".run.tmp-{p.pid}"
    killed.mkdir()
    (killed / "frames.csv").write_text("half")
    old = tmp_path / f".run.old-{p.pid}"
    old.mkdir()
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    live = tmp_path / f".run.tmp-{os.getppid()}"  # a live process (the test runner's parent)
    live.mkdir()
    other = tmp_path / ".run.tmp-notapid"
    other.mkdir()
    with atomic_dir(final) as tmp:
        (tmp / "x").write_text("ok")
    assert not killed.exists() and not old.exists()
    assert live.is_dir() and other.is_dir() and (final / "x").read_text() == "ok"


def test_a_run_killed_between_its_renames_gets_its_previous_output_back(tmp_path):
    """Killed after moving the previous output aside and before moving the new one in: no ``final``, a complete
    ``.old-PID`` and a ``.tmp-PID``. The next run puts the previous output back before it starts."""
    import signal
    import subprocess
    import sys

    from crowd.output import remove_stale_siblings

    final = tmp_path / "run"
    p = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    old = tmp_path / f".run.old-{p.pid}"
    old.mkdir()
    (old / "summary.json").write_text("{}")
    (tmp_path / f".run.tmp-{p.pid}").mkdir()
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    remove_stale_siblings(final)
    assert (final / "summary.json").read_text() == "{}"
    assert not old.exists() and not (tmp_path / f".run.tmp-{p.pid}").exists()
