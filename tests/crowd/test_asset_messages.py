"""A file the code cannot load is named with the scene and the key that pointed to it, and its full path
(issue 48, item 5): one line, exit 2, for validate and run alike."""
import pytest
from crowd_testutil import run_cli, tiny_scene


@pytest.mark.parametrize("content, what", [(b"glTF\x02\x00\x00\x00\xff\xff\x00\x00" + b"\x00" * 20, "truncated GLB"),
                                           (b"garbage", "truncated GLB")])
def test_a_broken_character_file_names_scene_key_and_path(write_scene, tmp_path, content, what):
    asset = tmp_path / "models" / "fox.glb"
    asset.parent.mkdir()
    asset.write_bytes(content)
    text = tiny_scene(replace={'generator = "humanoid"\ntriangles = 600': f'file = "{asset}"'})
    scene = write_scene(text)
    for cmd in (["validate", scene], ["run", scene, "--out", tmp_path / "out"]):
        r = run_cli(*cmd)
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
        assert f"{scene}: characters[0].file: {asset}: {what}" in lines[0], lines[0]
    assert not (tmp_path / "out").exists()
