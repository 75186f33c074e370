"""A glfw window for the fly-through: context, blit of the renderer's frame, HUD text.

- :class:`Window` opens a glfw window with an OpenGL core context (4.5
  requested, 3.3 as fallback), wraps it in a moderngl context (handed to
  :class:`render.renderer.Renderer` as ``ctx``), forwards glfw's input
  callbacks to a handler object's plain methods (``on_key``,
  ``on_mouse_button``, ``on_mouse_move``, ``on_scroll``, ``on_resize``) and
  copies the renderer's offscreen framebuffer to the window
  (``glBlitFramebuffer`` through ``ctx.copy_framebuffer``).
- :class:`Hud` draws text lines over the frame with a bitmap font: the atlas
  is rasterised once at start-up from Pillow's built-in bitmap font (no font
  file needed) into an R8 texture; each frame the lines are laid out with
  numpy (one quad per glyph, 6 vertices) into one dynamic buffer and drawn in
  one call, alpha-blended, together with a translucent panel behind them.
- :class:`VirtualDisplay` starts an ``Xvfb`` server on a free display number
  (``-displayfd``) for tests and benchmarks on machines without a display.

The window is the only place the fly-through touches glfw's GL side; nothing
here knows the simulation.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import time
from dataclasses import dataclass

import numpy as np

from render.context import REQUIRED_GL, ContextError
from render.shaders import program_sources

#: context versions requested, in order (major, minor), all core profile
GL_VERSIONS = ((4, 5), (3, 3))
#: first and last character code in the font atlas (printable ASCII); others draw as "?"
FONT_FIRST, FONT_LAST = 32, 126
#: atlas cell (index after the printable characters) that is fully covered: panels
SOLID_CELL = FONT_LAST - FONT_FIRST + 1
#: floats per HUD vertex: position (2, pixels), uv (2), colour (4)
HUD_VERTEX_FLOATS = 8
#: default HUD colours (straight RGBA)
HUD_TEXT_COLOR = (1.0, 1.0, 1.0, 1.0)
HUD_PANEL_COLOR = (0.0, 0.0, 0.0, 0.55)
#: panel padding around the text, pixels
HUD_PADDING = 4
#: Debian package providing the Xvfb binary
XVFB_PACKAGE = "xvfb"


class WindowError(ContextError):
    """No window could be opened (no display, or no OpenGL 3.3 core context on it)."""


def display_available(environ=None) -> bool:
    """True when a display server is named in the environment (X11 ``DISPLAY`` or ``WAYLAND_DISPLAY``)."""
    env = os.environ if environ is None else environ
    return bool(env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"))


# ---------------------------------------------------------------------------------------------------------------------
# font and text layout (no GL)
# ---------------------------------------------------------------------------------------------------------------------


@dataclass
class FontAtlas:
    """A bitmap font rasterised into one single-channel image.

    image : (H, W) uint8 coverage, row 0 at the top
    cell : (w, h) pixels of one glyph cell (every glyph is drawn as a full cell)
    advance : (n,) float32 pen advance per glyph, pixels; index = code - FONT_FIRST
    uv : (n + 1, 4) float32 (u0, v0, u1, v1) of each cell, v0 at the cell's top;
        the last row is the solid cell (:data:`SOLID_CELL`)
    line_height : int, pixels between baselines
    """

    image: np.ndarray
    cell: tuple
    advance: np.ndarray
    uv: np.ndarray
    line_height: int

    @classmethod
    def from_pillow(cls, scale: int = 1) -> "FontAtlas":
        """Rasterise Pillow's built-in bitmap font (ASCII 32..126), each pixel
        repeated ``scale`` times (integer >= 1, for high-DPI windows)."""
        from PIL import Image, ImageDraw, ImageFont

        scale = int(scale)
        if scale < 1:
            raise ValueError(f"FontAtlas scale: expected an integer >= 1, got {scale}")
        font = ImageFont.load_default_imagefont()
        chars = [chr(c) for c in range(FONT_FIRST, FONT_LAST + 1)]
        adv = np.array([font.getlength(c) for c in chars], np.float32)
        boxes = [font.getbbox(c) for c in chars]
        cw = int(max(adv.max(), max(b[2] for b in boxes)))
        ch = int(max(b[3] for b in boxes)) + 1
        n = len(chars) + 1  # + solid cell
        cols = 16
        rows = -(-n // cols)
        img = Image.new("L", (cols * cw, rows * ch), 0)
        draw = ImageDraw.Draw(img)
        for i, c in enumerate(chars):
            draw.text(((i % cols) * cw, (i // cols) * ch), c, font=font, fill=255)
        s = SOLID_CELL
        draw.rectangle([(s % cols) * cw, (s // cols) * ch, (s % cols + 1) * cw - 1, (s // cols + 1) * ch - 1], fill=255)
        a = np.asarray(img, np.uint8)
        if scale > 1:
            a = np.repeat(np.repeat(a, scale, axis=0), scale, axis=1)
        H, W = a.shape
        idx = np.arange(n)
        x0 = (idx % cols) * cw * scale
        y0 = (idx // cols) * ch * scale
        uv = np.stack([x0 / W, y0 / H, (x0 + cw * scale) / W, (y0 + ch * scale) / H], axis=1).astype(np.float32)
        # the solid cell samples its centre only, so linear/nearest filtering never reaches a neighbour
        cu, cv = (uv[s, 0] + uv[s, 2]) / 2, (uv[s, 1] + uv[s, 3]) / 2
        uv[s] = (cu, cv, cu, cv)
        return cls(np.ascontiguousarray(a), (cw * scale, ch * scale), adv * scale, uv, (ch + 1) * scale)


def glyph_indices(text: str) -> np.ndarray:
    """(len(text),) int64 atlas indices; characters outside printable ASCII map to "?"."""
    codes = np.frombuffer(text.encode("utf-32-le"), np.uint32).astype(np.int64)
    codes = np.where((codes < FONT_FIRST) | (codes > FONT_LAST), ord("?"), codes)
    return codes - FONT_FIRST


def layout_text(atlas: FontAtlas, lines, origin=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray, tuple]:
    """Glyph quads of text lines.

    Parameters
    ----------
    atlas : FontAtlas
    lines : sequence of str (no newlines; a "\\n" inside a line starts a new line)
    origin : (x, y) pixels of the first line's top-left corner (y down)

    Returns
    -------
    rects : (n, 4) float32 (x0, y0, x1, y1) pixels of the n non-blank glyphs
    uvs : (n, 4) float32 (u0, v0, u1, v1)
    extent : (width, height) pixels covered by the text
    """
    split = [part for line in lines for part in str(line).split("\n")]
    cw, chh = atlas.cell
    rects, uvs = [], []
    width = 0.0
    x, y = float(origin[0]), float(origin[1])
    space = ord(" ") - FONT_FIRST
    for li, line in enumerate(split):
        if not line:
            continue
        g = glyph_indices(line)
        adv = atlas.advance[g]
        pen = np.cumsum(adv) - adv
        width = max(width, float(pen[-1] + max(adv[-1], cw)) if len(adv) else 0.0)
        keep = g != space
        if not keep.any():
            continue
        px = x + pen[keep]
        py = np.full(px.shape, y + li * atlas.line_height, np.float32)
        rects.append(np.stack([px, py, px + cw, py + chh], axis=1))
        uvs.append(atlas.uv[g[keep]])
    height = float(len(split) * atlas.line_height) if split else 0.0
    if not rects:
        return np.zeros((0, 4), np.float32), np.zeros((0, 4), np.float32), (width, height)
    return (np.concatenate(rects).astype(np.float32), np.concatenate(uvs).astype(np.float32), (width, height))


def quad_vertices(rects: np.ndarray, uvs: np.ndarray, color) -> np.ndarray:
    """(n * 6, HUD_VERTEX_FLOATS) float32 triangle vertices of n quads.

    rects, uvs : (n, 4) float32 as from :func:`layout_text`; color : RGBA (4,) or (n, 4)
    """
    n = rects.shape[0]
    x0, y0, x1, y1 = rects.T
    u0, v0, u1, v1 = uvs.T
    # two triangles: (0,0) (1,0) (1,1) | (0,0) (1,1) (0,1)
    xs = np.stack([x0, x1, x1, x0, x1, x0], axis=1)
    ys = np.stack([y0, y0, y1, y0, y1, y1], axis=1)
    us = np.stack([u0, u1, u1, u0, u1, u0], axis=1)
    vs = np.stack([v0, v0, v1, v0, v1, v1], axis=1)
    out = np.empty((n, 6, HUD_VERTEX_FLOATS), np.float32)
    out[..., 0], out[..., 1], out[..., 2], out[..., 3] = xs, ys, us, vs
    out[..., 4:] = np.broadcast_to(np.asarray(color, np.float32).reshape(-1, 1, 4), (n, 6, 4))
    return out.reshape(n * 6, HUD_VERTEX_FLOATS)


# ---------------------------------------------------------------------------------------------------------------------
# HUD (GL)
# ---------------------------------------------------------------------------------------------------------------------


class Hud:
    """Text lines drawn over the current framebuffer in one draw call.

    Parameters
    ----------
    ctx : moderngl context
    scale : integer glyph magnification (1 = Pillow's 6x11-pixel bitmap font)

    ``draw(lines, size)`` draws into whatever framebuffer is bound (the
    window's), blending over it; it leaves blending and depth testing off.
    """

    def __init__(self, ctx, scale: int = 1):
        import moderngl

        self.ctx = ctx
        self.atlas = FontAtlas.from_pillow(scale)
        self._objects = []
        self.prog = self._track(ctx.program(**program_sources("hud")), "render.program.hud")
        a = self.atlas.image
        self.texture = self._track(ctx.texture((a.shape[1], a.shape[0]), 1, a.tobytes(), alignment=1),
                                   "render.hud.font")
        self.texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.texture.repeat_x = self.texture.repeat_y = False
        self._capacity = 0
        self.buffer = None
        self.vao = None
        self._grow(4096)
        self.vertices = 0  # vertices of the last draw
        self._released = False

    def _track(self, obj, label):
        try:
            obj.label = label
        except Exception:  # pragma: no cover - labels are best effort
            pass
        self._objects.append(obj)
        return obj

    def _grow(self, vertices: int) -> None:
        if vertices <= self._capacity:
            return
        cap = max(self._capacity, 1024)
        while cap < vertices:
            cap *= 2
        for o in (self.vao, self.buffer):
            if o is not None:
                o.release()
                self._objects.remove(o)
        self.buffer = self._track(self.ctx.buffer(reserve=cap * HUD_VERTEX_FLOATS * 4, dynamic=True),
                                  "render.hud.vertices")
        self.vao = self._track(self.ctx.vertex_array(self.prog, [(self.buffer, "2f 2f 4f", "in_pos", "in_uv",
                                                                   "in_color")]), "render.hud.vao")
        self._capacity = cap

    def vertices_for(self, lines, origin=(8, 8), color=HUD_TEXT_COLOR, panel=HUD_PANEL_COLOR) -> np.ndarray:
        """(m, HUD_VERTEX_FLOATS) float32: the panel quad (if ``panel``) then the glyph quads."""
        rects, uvs, (w, h) = layout_text(self.atlas, lines, origin)
        parts = []
        if panel is not None and w > 0 and h > 0:
            p = HUD_PADDING
            box = np.array([[origin[0] - p, origin[1] - p, origin[0] + w + p, origin[1] + h + p]], np.float32)
            parts.append(quad_vertices(box, self.atlas.uv[SOLID_CELL][None], panel))
        if rects.shape[0]:
            parts.append(quad_vertices(rects, uvs, color))
        return np.concatenate(parts) if parts else np.zeros((0, HUD_VERTEX_FLOATS), np.float32)

    def draw(self, lines, size, origin=(8, 8), color=HUD_TEXT_COLOR, panel=HUD_PANEL_COLOR) -> int:
        """Draw ``lines`` at ``origin`` (pixels from the top-left) into the
        bound framebuffer of ``size`` (w, h); returns the glyph quads drawn."""
        data = self.vertices_for(lines, origin, color, panel)
        n = data.shape[0]
        self.vertices = n
        if n == 0:
            return 0
        self._grow(n)
        self.buffer.write(data.tobytes())
        ctx = self.ctx
        ctx.viewport = (0, 0, int(size[0]), int(size[1]))
        ctx.disable(ctx.DEPTH_TEST)
        ctx.enable(ctx.BLEND)
        ctx.blend_func = ctx.SRC_ALPHA, ctx.ONE_MINUS_SRC_ALPHA
        self.prog["u_screen"].value = (float(size[0]), float(size[1]))
        self.prog["u_font"].value = 0
        self.texture.use(0)
        self.vao.render(ctx.TRIANGLES, vertices=n)
        ctx.disable(ctx.BLEND)
        return n // 6

    def release(self) -> None:
        """Release the GL objects in reverse creation order (safe twice)."""
        if self._released:
            return
        self._released = True
        for o in reversed(self._objects):
            try:
                o.release()
            except Exception:  # pragma: no cover
                pass
        self._objects.clear()


# ---------------------------------------------------------------------------------------------------------------------
# window
# ---------------------------------------------------------------------------------------------------------------------

_HANDLER_METHODS = ("on_key", "on_mouse_button", "on_mouse_move", "on_scroll", "on_resize")


class Window:
    """A glfw window with a moderngl context of OpenGL >= 3.3 core.

    Parameters
    ----------
    size : (width, height) window size in screen coordinates
    title : window title
    visible : show the window (tests may hide it; it still renders)
    vsync : swap interval 1 (True) or 0

    Raises
    ------
    WindowError
        No display (``DISPLAY``/``WAYLAND_DISPLAY`` unset), glfw could not
        initialise, or no core context of version 3.3 or above.

    Attributes
    ----------
    handle : the glfw window
    ctx : moderngl.Context of the window
    gl_version : (major, minor) requested successfully
    """

    def __init__(self, size=(1280, 720), title: str = "crowd", visible: bool = True, vsync: bool = False):
        import glfw
        import moderngl

        self._glfw = glfw
        if not display_available():
            raise WindowError("no display: neither DISPLAY nor WAYLAND_DISPLAY is set")
        if not glfw.init():
            raise WindowError(f"glfw could not initialise on display {os.environ.get('DISPLAY') or os.environ.get('WAYLAND_DISPLAY')!r}")
        w, h = int(size[0]), int(size[1])
        self.handle = None
        for major, minor in GL_VERSIONS:
            glfw.default_window_hints()
            glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, major)
            glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, minor)
            glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
            glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
            glfw.window_hint(glfw.VISIBLE, bool(visible))
            glfw.window_hint(glfw.DOUBLEBUFFER, True)
            self.handle = glfw.create_window(w, h, title, None, None)
            if self.handle:
                self.gl_version = (major, minor)
                break
        if not self.handle:
            glfw.terminate()
            raise WindowError(f"no OpenGL {REQUIRED_GL // 100}.{REQUIRED_GL // 10 % 10} core context could be created "
                              "for a window on this display")
        glfw.make_context_current(self.handle)
        glfw.swap_interval(1 if vsync else 0)
        try:
            self.ctx = moderngl.create_context(require=REQUIRED_GL)
        except Exception as exc:  # moderngl raises plain Exceptions
            glfw.destroy_window(self.handle)
            glfw.terminate()
            raise WindowError(f"the window's OpenGL context is unusable ({exc})") from exc
        self.handler = None
        self._closed = False

    # -- input ---------------------------------------------------------------------------------------------------------
    def attach(self, handler) -> None:
        """Route glfw's callbacks to ``handler``'s plain methods: ``on_key(key, action, mods)``,
        ``on_mouse_button(button, action, mods)``, ``on_mouse_move(x, y)``, ``on_scroll(dx, dy)``,
        ``on_resize(width, height)`` (framebuffer pixels). Missing methods are ignored."""
        glfw = self._glfw
        self.handler = handler
        glfw.set_key_callback(self.handle, self.key_callback)
        glfw.set_mouse_button_callback(self.handle, self.mouse_button_callback)
        glfw.set_cursor_pos_callback(self.handle, self.cursor_pos_callback)
        glfw.set_scroll_callback(self.handle, self.scroll_callback)
        glfw.set_framebuffer_size_callback(self.handle, self.framebuffer_size_callback)

    def _call(self, name, *args):
        fn = getattr(self.handler, name, None) if self.handler is not None else None
        if fn is not None:
            fn(*args)

    # the functions glfw calls (tests call them too)
    def key_callback(self, window, key, scancode, action, mods):
        self._call("on_key", key, action, mods)

    def mouse_button_callback(self, window, button, action, mods):
        self._call("on_mouse_button", button, action, mods)

    def cursor_pos_callback(self, window, x, y):
        self._call("on_mouse_move", float(x), float(y))

    def scroll_callback(self, window, dx, dy):
        self._call("on_scroll", float(dx), float(dy))

    def framebuffer_size_callback(self, window, width, height):
        self._call("on_resize", int(width), int(height))

    # -- state ---------------------------------------------------------------------------------------------------------
    @property
    def framebuffer_size(self) -> tuple:
        """(width, height) of the window's framebuffer, pixels."""
        return tuple(int(v) for v in self._glfw.get_framebuffer_size(self.handle))

    @property
    def should_close(self) -> bool:
        return bool(self._glfw.window_should_close(self.handle))

    def request_close(self) -> None:
        self._glfw.set_window_should_close(self.handle, True)

    def set_size(self, size) -> None:
        """Ask the window system for a new window size (the resize callback follows)."""
        self._glfw.set_window_size(self.handle, int(size[0]), int(size[1]))

    def set_title(self, title: str) -> None:
        self._glfw.set_window_title(self.handle, title)

    def poll(self) -> None:
        """Process pending window events (callbacks run here)."""
        self._glfw.poll_events()

    def swap(self) -> None:
        self._glfw.swap_buffers(self.handle)

    # -- drawing -------------------------------------------------------------------------------------------------------
    def blit(self, fbo) -> None:
        """Copy ``fbo``'s colour (a framebuffer of the window's size) to the window and
        leave the window's framebuffer bound with a full-window viewport."""
        ctx = self.ctx
        ctx.copy_framebuffer(ctx.screen, fbo)
        ctx.screen.use()
        ctx.viewport = (0, 0) + self.framebuffer_size

    def clear(self, color=(0.0, 0.0, 0.0)) -> None:
        ctx = self.ctx
        ctx.screen.use()
        ctx.viewport = (0, 0) + self.framebuffer_size
        ctx.clear(*tuple(color)[:3], 1.0)

    def read_pixels(self) -> np.ndarray:
        """(h, w, 3) uint8 of the window's back buffer (what the next swap shows), top row first."""
        w, h = self.framebuffer_size
        raw = self.ctx.screen.read(viewport=(0, 0, w, h), components=3, alignment=1)
        return np.frombuffer(raw, np.uint8).reshape(h, w, 3)[::-1].copy()

    def close(self) -> None:
        """Destroy the window and terminate glfw (safe twice). Release GL objects made on
        ``ctx`` before calling this."""
        if self._closed:
            return
        self._closed = True
        glfw = self._glfw
        glfw.destroy_window(self.handle)
        glfw.terminate()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


# ---------------------------------------------------------------------------------------------------------------------
# Xvfb
# ---------------------------------------------------------------------------------------------------------------------


class VirtualDisplay:
    """An ``Xvfb`` X server on a free display number (for tests and benchmarks).

    ``with VirtualDisplay() as d: os.environ["DISPLAY"] = d.display``. The
    server picks its own free number (``-displayfd``) and is terminated on exit.

    Raises
    ------
    FileNotFoundError : the Xvfb binary is missing (message names the package).
    RuntimeError : the server did not come up within ``timeout`` seconds.
    """

    def __init__(self, screen: str = "1280x1024x24", timeout: float = 20.0):
        self.screen = screen
        self.timeout = float(timeout)
        self.proc = None
        self.display = None

    def start(self) -> "VirtualDisplay":
        exe = shutil.which("Xvfb")
        if exe is None:
            raise FileNotFoundError(f"the Xvfb binary is missing; install the Debian package {XVFB_PACKAGE!r} "
                                    f"(apt-get install {XVFB_PACKAGE}, as the README set-up does)")
        r, w = os.pipe()
        try:
            self.proc = subprocess.Popen([exe, "-displayfd", str(w), "-screen", "0", self.screen, "-nolisten", "tcp"],
                                         pass_fds=(w,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        finally:
            os.close(w)
        try:
            deadline = time.monotonic() + self.timeout
            buf = b""
            os.set_blocking(r, False)
            while not buf.endswith(b"\n"):
                if self.proc.poll() is not None:
                    raise RuntimeError(f"Xvfb exited with code {self.proc.returncode} before opening a display")
                if time.monotonic() > deadline:
                    raise RuntimeError(f"Xvfb did not report a display within {self.timeout:g} s")
                try:
                    chunk = os.read(r, 64)
                except BlockingIOError:
                    time.sleep(0.02)
                    continue
                if not chunk:
                    time.sleep(0.02)
                buf += chunk
            self.display = ":" + buf.decode().strip()
        except BaseException:
            self.stop()
            raise
        finally:
            os.close(r)
        return self

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:  # pragma: no cover
                self.proc.kill()
                self.proc.wait()
        self.proc = None

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()
