"""Project plumbing: `make test` fails when pytest collects nothing; CI calls the README's test command."""
import os
import shutil
import subprocess

import pytest

from crowd_testutil import REPO

pytestmark = pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")


def _make_test(tmp_path, rc: int):
    venv = tmp_path / "venv"
    venv.mkdir()
    (venv / ".crowd-setup-done").touch()  # newer than pyproject.toml: set-up is skipped
    fake = tmp_path / "fakepy"
    fake.write_text(f"#!/bin/sh\necho \"fake pytest $*\"\nexit {rc}\n")
    fake.chmod(0o755)
    return subprocess.run(["make", "--no-print-directory", "-C", str(REPO), "test", f"VENV={venv}", f"VPY={fake}"],
                          capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize("rc, ok", [(0, True), (1, False), (2, False), (5, False)])
def test_make_test_exit_status(tmp_path, rc, ok):
    r = _make_test(tmp_path, rc)
    assert (r.returncode == 0) == ok, r.stdout + r.stderr
    assert "fake pytest -m pytest" in r.stdout
    if rc == 5:
        assert "collected no tests" in r.stderr


def test_setup_is_idempotent_with_its_sentinel(tmp_path):
    venv = tmp_path / "venv"
    venv.mkdir()
    (venv / ".crowd-setup-done").touch()
    r = subprocess.run(["make", "-C", str(REPO), "-q", "setup", f"VENV={venv}"], capture_output=True, text=True)
    assert r.returncode == 0  # up to date: nothing to do


def test_ci_runs_the_readme_test_command():
    ci = REPO / ".ci" / "run"
    assert os.access(ci, os.X_OK)
    text = ci.read_text()
    assert "set -euo pipefail" in text and "make test" in text
    readme = (REPO / "README.md").read_text()
    assert "make demo" in readme and "make test" in readme
