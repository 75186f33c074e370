"""Fixtures of the crowd tests."""
import pytest


@pytest.fixture
def write_scene(tmp_path):
    def write(text, name="scene.toml"):
        p = tmp_path / name
        p.write_text(text)
        return p
    return write
