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


def test_soak_cli_bad_scene_exit_2(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("frames = -1\n")
    r = subprocess.run([sys.executable, str(REPO / "scripts" / "soak.py"), str(bad), "--seconds", "1"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "bad.toml" in r.stderr and "Traceback" not in r.stderr
