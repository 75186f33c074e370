"""Fixtures of the hard-case suite: one headless EGL context per module (never
skipped: llvmpipe through EGL exists on every machine), debug renderers that
refuse NaN/Inf instance data, and the tiny hand-made characters."""
import os

import pytest

os.environ.setdefault("CROWD_GL_DEBUG", "1")


@pytest.fixture(scope="module")
def gl_ctx():
    from render.context import create_context

    ctx = create_context()
    yield ctx
    ctx.release()
