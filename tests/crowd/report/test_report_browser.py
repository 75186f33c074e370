"""The report page in headless Chromium: the plots show in a screenshot, every image loads, the console is quiet.

Chromium is the Debian package ``chromium`` (``make setup`` installs it); without it this test fails rather than
skips, since a browser check that skips checks nothing.
"""
import json
import re
import shutil
import subprocess

import numpy as np
import pytest
from crowd_testutil import run_cli, tiny_scene

from crowd.images import read_png

SCENE = tiny_scene(replace={"frames = 3": "frames = 4", "size = [64, 48]": "size = [96, 72]",
                            "png_every = 1": "png_every = 0"})
#: browser window (CSS pixels = screenshot pixels at scale factor 1): tall enough for every plot of the page
WINDOW = (1280, 3400)
#: injected first in <head>: records script errors, console errors and failed resource loads
PROBE_HEAD = """<script>
window.__crowdErrors = [];
window.addEventListener('error', function (ev) {
  var t = ev.target;
  if (t && t.tagName === 'IMG') { if (t.id !== 'crowd-control') window.__crowdErrors.push('img ' + t.getAttribute('src')); }
  else { window.__crowdErrors.push('error ' + ev.message); }
}, true);
['error', 'warn'].forEach(function (k) { var f = console[k];
  console[k] = function () { window.__crowdErrors.push(k + ' ' + Array.prototype.join.call(arguments, ' ')); f.apply(console, arguments); }; });
</script>"""
#: injected last in <body>: a control image that must fail, then the result as JSON in <pre id="crowd-check">
PROBE_BODY = """<img id="crowd-control" src="plots/__missing__.png" alt="control">
<script>
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images).map(function (im) { var r = im.getBoundingClientRect();
    return {src: im.getAttribute('src'), id: im.id, ok: im.complete && im.naturalWidth > 0, w: im.naturalWidth,
            h: im.naturalHeight, x: r.left + window.scrollX, y: r.top + window.scrollY, width: r.width,
            height: r.height}; });
  var pre = document.createElement('pre'); pre.id = 'crowd-check';
  pre.textContent = JSON.stringify({images: imgs, errors: window.__crowdErrors});
  document.body.appendChild(pre);
});
</script>"""


def _chromium() -> str:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        pytest.fail("chromium is not installed: `make setup` installs it (apt-get install chromium)")
    return exe


def _browse(exe, url, *flags):
    cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--force-device-scale-factor=1",
           f"--window-size={WINDOW[0]},{WINDOW[1]}", "--enable-logging=stderr", "--v=0",
           "--virtual-time-budget=10000", *flags, url]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120)


def _console_lines(stderr: str) -> list:
    """Chromium's log lines of page console messages (``...:CONSOLE:<line>] "message", source: ...``)."""
    return [x for x in stderr.splitlines() if ":CONSOLE" in x]


def test_report_page_in_headless_chromium(write_scene, tmp_path):
    exe = _chromium()
    out = tmp_path / "rep"
    r = run_cli("report", write_scene(SCENE), "--sweep", "lod.mode=none,points", "--out", out, "--sample-every", "2",
                "--cluster", "none", "--quiet")
    assert r.returncode == 0, r.stderr
    page = (out / "index.html").read_text()
    srcs = re.findall(r"<img src='([^']+)'", page)
    # 7 plots; 3 settings (aliased full detail added) x 2 sampled frames x (frame, reference, error map)
    assert len(srcs) == 7 + 3 * 2 * 3

    # every image loads, no script/console error; the control image (a missing file) is the only one that fails
    probe = out / "probe.html"
    probe.write_text(page.replace("<style>", PROBE_HEAD + "<style>", 1).replace("</body>", PROBE_BODY + "</body>"))
    b = _browse(exe, probe.as_uri(), "--dump-dom")
    assert b.returncode == 0, b.stderr[-2000:]
    m = re.search(r'<pre id="crowd-check">(.*?)</pre>', b.stdout, re.S)
    assert m, "the probe did not run: " + b.stderr[-2000:]
    check = json.loads(m.group(1).replace("&quot;", '"').replace("&amp;", "&"))
    imgs = {i["src"]: i for i in check["images"]}
    assert [i["src"] for i in check["images"] if i["id"] != "crowd-control"] == srcs
    assert not imgs["plots/__missing__.png"]["ok"]  # the check can fail
    assert [i["src"] for i in check["images"] if not i["ok"] and i["id"] != "crowd-control"] == []
    assert check["errors"] == []
    assert _console_lines(b.stderr) == []

    # the plain page: no console message at all; the screenshot shows each plot where the page lays it out
    shot = tmp_path / "shot.png"
    b = _browse(exe, (out / "index.html").as_uri(), f"--screenshot={shot}")
    assert b.returncode == 0 and shot.is_file(), b.stderr[-2000:]
    assert _console_lines(b.stderr) == []
    px = read_png(shot).astype(np.int16)
    assert px.shape[:2] == (WINDOW[1], WINDOW[0])
    plots = [i for i in check["images"] if i["src"].startswith("plots/") and i["id"] != "crowd-control"]
    assert len(plots) == 7 and all(i["y"] + i["height"] <= WINDOW[1] for i in plots), "a plot is below the window"
    for i in plots:
        w, h = int(round(i["width"])), int(round(i["height"]))
        png = read_png(out / i["src"]).astype(np.int16)
        assert (h, w) == png.shape[:2]  # drawn 1:1 at scale factor 1
        # the layout may put an image at a half pixel: take the whole-pixel position that matches best
        x, y = min(((int(i["x"]) + dx, int(i["y"]) + dy) for dx in (0, 1) for dy in (0, 1)),
                   key=lambda p: np.abs(px[p[1]:p[1] + h, p[0]:p[0] + w] - png).mean())
        region = px[y:y + h, x:x + w]
        ink = np.any(region < 200, axis=2).mean()  # axes, labels, lines: not the white background
        colour = (region.max(axis=2) - region.min(axis=2) > 80).sum()  # the coloured curves / markers / areas
        assert 0.01 < ink < 0.9 and colour > 100, (i["src"], ink, colour)
        # the region is the plot's own PNG
        assert np.abs(region - png).mean() < 2.0, i["src"]
        # beside the plot (its rows, right of it) the screenshot is background: the ink above is the plot's
        right = px[y:y + h, x + w + 8:]
        assert right.size and np.all(right > 240), i["src"]
