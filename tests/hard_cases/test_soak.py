"""scripts/soak.py: a short run reports frames, memory figures and GL errors."""
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

import soak  # noqa: E402

SCENE = """
name = "soaky"
frames = 5
effects = ["animation"]
[[characters]]
name = "w"
generator = "humanoid"
triangles = 600
[[placement]]
kind = "grid"
character = "w"
rows = 2
cols = 2
[render]
size = [48, 32]
raster_threshold = 0  # the hardware path's submissions are what the soak counts (not the compute rasteriser's)
"""


def test_soak_short_run_reports_memory_and_errors(tmp_path):
    p = tmp_path / "soaky.toml"
    p.write_text(SCENE)
    r = soak.soak(str(p), seconds=1.5, warmup=0.5, quiet=True, trim=True)
    assert r["frames"] >= 2 and r["gl_errors"] == 0 and r["gl_error_kinds"] == {}
    assert 0 < r["rss_start"] <= r["rss_max"] and r["rss_end"] > 0
    text = soak.format_report(r)
    assert "memory growth after warm-up" in text and "GL errors: 0" in text
    assert soak.resident_bytes() > 10_000_000
    assert r["heap_start"] > 0 and r["heap_end"] > 0 and "C heap in use" in text
    assert r["submissions_per_frame"] >= 1 and r["max_triangles_in_flight"] > 0
    assert soak.heap_in_use() > 1_000_000


def test_soak_split_off_and_tiny_limit(tmp_path):
    """``max_triangles_in_flight``: 0 turns the renderer's split off; a limit
    below one character's triangles gives one submission per instance."""
    p = tmp_path / "soaky.toml"
    p.write_text(SCENE)
    off = soak.soak(str(p), seconds=0.5, warmup=0.1, quiet=True, max_triangles_in_flight=0)
    assert off["max_triangles_in_flight"] is None and off["submissions_per_frame"] == 1.0
    one = soak.soak(str(p), seconds=0.5, warmup=0.1, quiet=True, max_triangles_in_flight=1)
    assert one["submissions_per_frame"] == 4.0 and one["gl_errors"] == 0  # 2 x 2 grid, one instance each
    assert "no limit" in soak.format_report(off)


def test_soak_cli_bad_scene_exit_2(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("frames = -1\n")
    r = subprocess.run([sys.executable, str(REPO / "scripts" / "soak.py"), str(bad), "--seconds", "1"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "bad.toml" in r.stderr and "Traceback" not in r.stderr
