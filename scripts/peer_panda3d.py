"""The Panda3D side of ``scripts/bench_peer.py``: one scenario, timed, as JSON on stdout.

Runs in the benchmark-only peers interpreter (``make bench-peers`` -> ``.venv-peers``: panda3d,
panda3d-gltf), never in the project's: it imports nothing of the project. Input is one JSON object on
stdin (the scenario ``bench_peer.py`` computed, in the project's Y-up metres):

    {"model": path, "clip": name or "", "positions": [[x, y, z], ...], "eye": [x, y, z],
     "target": [x, y, z], "fov": 50.0, "near": 0.1, "far": 1000.0, "size": [1280, 720],
     "frames": 5, "warmup": 2, "hardware_skinning": false, "light": true}

Panda3D renders through its own OpenGL renderer (``load-display p3headlessgl``, an offscreen buffer; on
this machine Mesa llvmpipe, as ours); one ``Actor`` per copy, looping its clip; a sun and an ambient
light (the fixed-function lighting Panda3D uses without a shader generator). A frame is one
``taskMgr.step()`` (animation, cull, draw) followed by ``glFinish`` (through ctypes on the current
context), so the clock stops when the frame is rendered, as ours stops after ``ctx.finish``.

Output: {"frames_s": [...], "median_s": m, "cpu_s": [...] (CPU seconds of every thread of the process per
frame, Panda3D's and the driver's: the work, which a machine shared with other jobs does not distort as it does
the wall time), "renderer": GL renderer string, "panda3d": version,
"actors": n, "load_s": seconds to load and place the actors}.
"""
from __future__ import annotations

import ctypes
import json
import math
import statistics
import sys
import time


def _gl_finish():
    for name in ("libGL.so.1", "libOpenGL.so.0", "libGL.so"):
        try:
            return ctypes.CDLL(name).glFinish
        except OSError:
            continue
    return lambda: None


def main() -> int:
    spec = json.load(sys.stdin)
    from panda3d.core import (AmbientLight, DirectionalLight, PandaSystem, PerspectiveLens, Vec3,
                              loadPrcFileData)

    w, h = spec.get("size", [1280, 720])
    loadPrcFileData("", "\n".join([
        "load-display p3headlessgl", "window-type offscreen", f"win-size {int(w)} {int(h)}",
        "audio-library-name null", "sync-video false", "framebuffer-multisample 0", "multisamples 0",
        "notify-level warning", "default-directnotify-level warning",
        f"hardware-animated-vertices {'true' if spec.get('hardware_skinning') else 'false'}",
    ]))
    from direct.actor.Actor import Actor
    from direct.showbase.ShowBase import ShowBase

    base = ShowBase()
    base.disableMouse()
    finish = _gl_finish()

    def z_up(p):  # the project's Y-up (x, y, z) -> Panda3D's Z-up (x, -z, y)
        return Vec3(float(p[0]), -float(p[2]), float(p[1]))

    t0 = time.perf_counter()
    clip = spec.get("clip") or ""
    proto = Actor(spec["model"])
    names = proto.getAnimNames()
    if names and clip not in names:
        clip = names[0]
    actors = []
    phases = spec.get("phases")  # seconds into the clip per copy (None: every copy from time 0)
    for i, p in enumerate(spec["positions"]):
        a = Actor(spec["model"])
        a.reparentTo(base.render)
        a.setPos(z_up(p))
        if clip:
            a.loop(clip)
            if phases is not None:  # start the loop at the copy's phase
                ac = a.getAnimControl(clip)
                ac.pose(float(phases[i]) * ac.getFrameRate() % max(1, ac.getNumFrames()))
                ac.loop(False)
        actors.append(a)
    proto.cleanup()
    load_s = time.perf_counter() - t0
    if spec.get("light", True):
        sun = DirectionalLight("sun")
        sun.setColor((0.8, 0.8, 0.8, 1))
        sn = base.render.attachNewNode(sun)
        sn.lookAt(z_up([-0.35, -0.85, -0.4]))
        amb = AmbientLight("ambient")
        amb.setColor((0.3, 0.3, 0.3, 1))
        base.render.setLight(sn)
        base.render.setLight(base.render.attachNewNode(amb))
    lens = PerspectiveLens()
    lens.setAspectRatio(w / h)
    lens.setNearFar(float(spec.get("near", 0.1)), float(spec.get("far", 1000.0)))
    vfov = float(spec.get("fov", 50.0))
    hfov = math.degrees(2 * math.atan(math.tan(math.radians(vfov) / 2) * w / h))
    lens.setFov(hfov, vfov)
    base.cam.node().setLens(lens)
    base.camera.setPos(z_up(spec["eye"]))
    base.camera.lookAt(z_up(spec["target"]), Vec3(0, 0, 1))
    base.setBackgroundColor(0.1, 0.1, 0.12, 1)
    times, cpu = [], []
    for k in range(int(spec.get("warmup", 2)) + int(spec.get("frames", 5))):
        t, c = time.perf_counter(), time.process_time()
        base.taskMgr.step()
        finish()
        if k >= int(spec.get("warmup", 2)):
            times.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
    gsg = base.win.getGsg()
    out = {"frames_s": times, "median_s": statistics.median(times) if times else None, "cpu_s": cpu,
           "renderer": f"{gsg.getDriverRenderer()} ({gsg.getDriverVersion()})",
           "panda3d": PandaSystem.getVersionString(), "actors": len(actors), "load_s": load_s, "clip": clip}
    if spec.get("screenshot"):
        base.win.saveScreenshot(spec["screenshot"])
    json.dump(out, sys.stdout)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
