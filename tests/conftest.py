"""Session-wide test settings.

Hierarchy caches (points, clusters) go to a fresh folder per test session, so
tests never read or fill the user's ``~/.cache/crowd`` and always exercise a
cold cache first. Subprocesses inherit it through the environment.

The shared test helpers of ``tests/fixtures`` (tiny characters, image checks)
are importable from every test folder.
"""
import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent / "fixtures"))


@pytest.fixture(scope="session", autouse=True)
def _isolated_cache(tmp_path_factory):
    old = os.environ.get("CROWD_CACHE_DIR")
    os.environ["CROWD_CACHE_DIR"] = str(tmp_path_factory.mktemp("crowd-cache"))
    yield
    if old is None:
        os.environ.pop("CROWD_CACHE_DIR", None)
    else:
        os.environ["CROWD_CACHE_DIR"] = old


@pytest.fixture(scope="module")
def display():
    """An Xvfb server for the tests of one module that open windows (render.window,
    crowd fly); ``DISPLAY`` names it while the module runs. A missing Xvfb fails
    the tests (CI installs the Debian package ``xvfb``), never skips them."""
    from render.window import VirtualDisplay

    try:
        vd = VirtualDisplay().start()
    except FileNotFoundError as e:
        pytest.fail(f"{e}: tests that open a window need Xvfb (Debian package xvfb)")
    old = os.environ.get("DISPLAY")
    os.environ["DISPLAY"] = vd.display
    yield vd.display
    if old is None:
        os.environ.pop("DISPLAY", None)
    else:
        os.environ["DISPLAY"] = old
    vd.stop()
