"""GL test fixtures: one headless EGL context per test module (never skipped:
Mesa llvmpipe through EGL is available on every development and CI machine)."""
import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fixtures"))
# every Renderer made by a test checks its instance data for NaN/Inf
os.environ.setdefault("CROWD_GL_DEBUG", "1")


@pytest.fixture(scope="module")
def gl_ctx():
    from render.context import create_context

    ctx = create_context()
    yield ctx
    ctx.release()
