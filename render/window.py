"""A glfw window for the fly-through: context, blit of the renderer's frame, HUD text.

- :class:`Window` opens a glfw window with an OpenGL core context (4.5
  requested, 3.3 as fallback), wraps it in a moderngl context (handed to
  :class:`render.renderer.Renderer` as ``ctx``), forwards glfw's input
  callbacks to a handler object's plain methods (``on_key``,
  ``on_mouse_button``, ``on_mouse_move``, ``on_scroll``, ``on_resize``) and
  copies the renderer's offscreen framebuffer to the window
  (``glBlitFramebuffer`` through ``ctx.copy_framebuffer``).
- :class:`Hud` draws text lines over the frame with a bitmap font: glyph
  cells are rasterised once at start-up from Pillow's built-in bitmap font (no
  font file needed); each frame the lines become one coverage image by a numpy
  gather of those cells, uploaded into an R8 texture and drawn as one
  alpha-blended quad (text over a translucent panel).
- :class:`VirtualDisplay` starts an ``Xvfb`` server on a free display number
  (``-displayfd``) for tests and benchmarks on machines without a display.

The window is the only place the fly-through touches glfw's GL side; nothing
here knows the simulation.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import time
import warnings
from dataclasses import dataclass

import numpy as np

from render.context import REQUIRED_GL, ContextError, release_all, track
from render.shaders import program_sources

#: context versions requested, in order (major, minor), all core profile
GL_VERSIONS = ((4, 5), (3, 3))
#: first and last character code in the font atlas (printable ASCII); others draw as "?"
FONT_FIRST, FONT_LAST = 32, 126
#: floats per HUD vertex: position (2, pixels), uv (2)
HUD_VERTEX_FLOATS = 4
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
    """A monospaced bitmap font as an array of glyph cells.

    cells : (n, line_height, advance) uint8 coverage (0 or 255) of the printable
        ASCII characters, index = code - FONT_FIRST; each cell includes the
        spacing below the glyph, so cells stacked and side by side make text.
    """

    cells: np.ndarray

    def __post_init__(self):
        self.cells = np.ascontiguousarray(self.cells, np.uint8)
        #: (line_height, n, advance) view of the cells by row, for fast gathers
        self.rows = np.ascontiguousarray(self.cells.transpose(1, 0, 2))

    @property
    def advance(self) -> int:
        """Pixels from one character to the next."""
        return int(self.cells.shape[2])

    @property
    def line_height(self) -> int:
        """Pixels from one line to the next."""
        return int(self.cells.shape[1])

    @classmethod
    def from_pillow(cls, scale: int = 1) -> "FontAtlas":
        """Rasterise Pillow's built-in bitmap font (ASCII 32..126, 6 pixels wide),
        each pixel repeated ``scale`` times (integer >= 1, for high-DPI windows)."""
        from PIL import Image, ImageDraw, ImageFont

        scale = int(scale)
        if scale < 1:
            raise ValueError(f"FontAtlas scale: expected an integer >= 1, got {scale}")
        font = ImageFont.load_default_imagefont()
        chars = [chr(c) for c in range(FONT_FIRST, FONT_LAST + 1)]
        cw = int(max(max(font.getlength(c) for c in chars), max(font.getbbox(c)[2] for c in chars)))
        ch = int(max(font.getbbox(c)[3] for c in chars)) + 2  # + line spacing
        img = Image.new("L", (cw * len(chars), ch), 0)
        draw = ImageDraw.Draw(img)
        for i, c in enumerate(chars):
            draw.text((i * cw, 0), c, font=font, fill=255)
        a = np.asarray(img, np.uint8).reshape(ch, len(chars), cw).transpose(1, 0, 2)
        a = np.where(a > 127, 255, 0).astype(np.uint8)
        if scale > 1:
            a = np.repeat(np.repeat(a, scale, axis=1), scale, axis=2)
        return cls(np.ascontiguousarray(a))


def glyph_indices(text: str) -> np.ndarray:
    """(len(text),) int64 cell indices; characters outside printable ASCII map to "?"."""
    codes = np.frombuffer(text.encode("utf-32-le"), np.uint32).astype(np.int64)
    codes = np.where((codes < FONT_FIRST) | (codes > FONT_LAST), ord("?"), codes)
    return codes - FONT_FIRST


def rasterize_text(atlas: FontAtlas, lines, padding: int = 0) -> np.ndarray:
    """Text lines as one coverage image, by a single gather of glyph cells.

    Parameters
    ----------
    atlas : FontAtlas
    lines : sequence of str (characters outside printable ASCII draw as "?")
    padding : empty pixels around the text

    Returns
    -------
    (len(lines) * line_height + 2 * padding, longest * advance + 2 * padding) uint8,
    row 0 at the top; (0, 0) when there is no text.
    """
    lines = [str(x) for x in lines]
    longest = max((len(x) for x in lines), default=0)
    if longest == 0:
        return np.zeros((0, 0), np.uint8)
    space = ord(" ") - FONT_FIRST
    g = np.full((len(lines), longest), space, np.int64)
    for i, line in enumerate(lines):
        if line:
            g[i, :len(line)] = glyph_indices(line)
    lh, cw = atlas.line_height, atlas.advance
    L = len(lines)
    out = np.zeros((L * lh + 2 * padding, longest * cw + 2 * padding), np.uint8)
    # gather cells by row: (cell row, line, character, cell column), then one strided copy
    text = np.take(atlas.rows, g, axis=1)
    out[padding:padding + L * lh, padding:padding + longest * cw].reshape(L, lh, longest, cw)[...] = \
        text.transpose(1, 0, 2, 3)
    return out


# ---------------------------------------------------------------------------------------------------------------------
# HUD (GL)
# ---------------------------------------------------------------------------------------------------------------------


class Hud:
    """Text lines drawn over the current framebuffer as one textured quad.

    Each frame the lines are rasterised on the CPU (:func:`rasterize_text`, one
    numpy gather of glyph cells), written into a part of one R8 texture and
    drawn as a single alpha-blended quad whose fragment shader mixes the panel
    colour (where there is no glyph) with the text colour. On llvmpipe this is
    far cheaper than a quad per glyph, whose triangle set-up dominated. Text
    equal to the last one drawn is not rasterised or uploaded again.

    Parameters
    ----------
    ctx : moderngl context
    scale : integer glyph magnification (1 = Pillow's 6-pixel-wide bitmap font)

    ``draw(lines, size)`` draws into whatever framebuffer is bound (the
    window's); it leaves blending and depth testing off.
    """

    def __init__(self, ctx, scale: int = 1):
        self.ctx = ctx
        self.atlas = FontAtlas.from_pillow(scale)
        self._objects = []
        self.prog = self._track(ctx.program(**program_sources("hud")), "render.program.hud")
        self.buffer = self._track(ctx.buffer(reserve=6 * HUD_VERTEX_FLOATS * 4, dynamic=True), "render.hud.quad")
        self.vao = self._track(ctx.vertex_array(self.prog, [(self.buffer, "2f 2f", "in_pos", "in_uv")]),
                               "render.hud.vao")
        self.texture = None
        self._tex_size = (0, 0)
        self._grow((256, 64))
        self.extent = (0, 0)  # (w, h) pixels of the last draw
        self.rasterized = 0  # texts rasterised and uploaded (a repeated text is not)
        self._text_key = None
        self._released = False

    def _track(self, obj, label: str):
        return track(self._objects, obj, label)  # render.context.track

    def _grow(self, size) -> None:
        import moderngl

        w, h = max(int(size[0]), self._tex_size[0]), max(int(size[1]), self._tex_size[1])
        if (w, h) == self._tex_size:
            return
        w, h = 1 << (w - 1).bit_length(), 1 << (h - 1).bit_length()  # powers of two: few re-allocations
        if self.texture is not None:
            self.texture.release()
            self._objects.remove(self.texture)
            self._text_key = None
        self.texture = self._track(self.ctx.texture((w, h), 1, alignment=1), "render.hud.text")
        self.texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.texture.repeat_x = self.texture.repeat_y = False
        self._tex_size = (w, h)

    def draw(self, lines, size, origin=(8, 8), color=HUD_TEXT_COLOR, panel=HUD_PANEL_COLOR) -> tuple:
        """Draw ``lines`` with their top-left corner at ``origin`` (pixels from the
        window's top-left) into the bound framebuffer of ``size`` (w, h).

        ``panel`` : RGBA behind the text (padding :data:`HUD_PADDING` pixels), or None.
        Returns the (w, h) pixels covered (0, 0 when there is no text).
        """
        pad = HUD_PADDING if panel is not None else 0
        key = (tuple(str(x) for x in lines), pad)
        if key != self._text_key:  # same text as last time: the texture already holds it
            img = rasterize_text(self.atlas, key[0], padding=pad)
            h, w = img.shape
            self.extent = (w, h)
            self._text_key = key if w and h else None
            if w == 0 or h == 0:
                return self.extent
            self._grow((w, h))
            self.texture.write(img, viewport=(0, 0, w, h), alignment=1)
            self.rasterized += 1
        w, h = self.extent
        tw, th = self._tex_size
        x0, y0 = float(origin[0] - pad), float(origin[1] - pad)
        quad = np.array([[x0, y0, 0.0, 0.0], [x0 + w, y0, w / tw, 0.0], [x0 + w, y0 + h, w / tw, h / th],
                         [x0, y0, 0.0, 0.0], [x0 + w, y0 + h, w / tw, h / th], [x0, y0 + h, 0.0, h / th]],
                        np.float32)
        self.buffer.write(quad.tobytes())
        ctx = self.ctx
        ctx.viewport = (0, 0, int(size[0]), int(size[1]))
        ctx.disable(ctx.DEPTH_TEST)
        ctx.enable(ctx.BLEND)
        ctx.blend_func = ctx.SRC_ALPHA, ctx.ONE_MINUS_SRC_ALPHA
        self.prog["u_screen"].value = (float(size[0]), float(size[1]))
        self.prog["u_text"].value = 0
        self.prog["u_color"].value = tuple(float(c) for c in color)
        self.prog["u_panel"].value = tuple(float(c) for c in panel) if panel is not None else (0.0, 0.0, 0.0, 0.0)
        self.texture.use(0)
        self.vao.render(ctx.TRIANGLES, vertices=6)
        ctx.disable(ctx.BLEND)
        return self.extent

    def release(self) -> None:
        """Release the GL objects in reverse creation order (safe twice)."""
        if self._released:
            return
        self._released = True
        release_all(self._objects)  # render.context: reverse order, each once


# ---------------------------------------------------------------------------------------------------------------------
# window
# ---------------------------------------------------------------------------------------------------------------------

#: windows open in this process; glfw is terminated when the last one closes
_open_windows = 0


def _glfw_error_text(err) -> str:
    """``b'X11: Failed to open display :9'`` out of a glfw error's "(code) b'...'" message."""
    text = str(err)
    m = re.match(r"^\(\d+\)\s*b(['\"])(.*)\1$", text)
    return m.group(2) if m else text


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
        global _open_windows
        with warnings.catch_warnings(record=True) as caught:  # glfw reports errors as warnings
            warnings.simplefilter("always")
            ok = glfw.init()
        if not ok:
            why = "; ".join(_glfw_error_text(w.message) for w in caught) or "no reason given"
            raise WindowError(f"glfw could not initialise: {why}")
        w, h = int(size[0]), int(size[1])
        self.handle = None
        # EGL first: once a process has used a headless EGL context (the engine's renderer, tests), Mesa refuses
        # GLX MakeCurrent with BadAccess, which Xlib turns into exit(1). With EGL on both sides they coexist; GLX
        # stays as the fallback for drivers without EGL window surfaces.
        self.context_api = None
        for api, major, minor in [(a, *v) for a in ("egl", "native") for v in GL_VERSIONS]:
            glfw.default_window_hints()
            glfw.window_hint(glfw.CONTEXT_CREATION_API,
                             glfw.EGL_CONTEXT_API if api == "egl" else glfw.NATIVE_CONTEXT_API)
            glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, major)
            glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, minor)
            glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
            glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
            glfw.window_hint(glfw.VISIBLE, bool(visible))
            glfw.window_hint(glfw.DOUBLEBUFFER, True)
            with warnings.catch_warnings():  # a refused version is expected: try the next one
                warnings.simplefilter("ignore")
                self.handle = glfw.create_window(w, h, title, None, None)
            if self.handle:
                self.gl_version = (major, minor)
                self.context_api = api
                break
        if not self.handle:
            if _open_windows == 0:
                glfw.terminate()
            raise WindowError(f"no OpenGL {REQUIRED_GL // 100}.{REQUIRED_GL // 10 % 10} core context could be created "
                              "for a window on this display")
        glfw.make_context_current(self.handle)
        glfw.swap_interval(1 if vsync else 0)
        try:
            if self.context_api == "egl":
                # glcontext's EGL backend cannot adopt glfw's context; "share" makes a context sharing its
                # objects and drawing to the current window surface
                self.ctx = moderngl.create_context(require=REQUIRED_GL, share=True, backend="egl")
            else:
                self.ctx = moderngl.create_context(require=REQUIRED_GL)
        except Exception as exc:  # moderngl raises plain Exceptions
            glfw.destroy_window(self.handle)
            if _open_windows == 0:
                glfw.terminate()
            raise WindowError(f"the window's OpenGL context is unusable ({exc})") from exc
        self.handler = None
        self._closed = False
        _open_windows += 1

    # -- input ---------------------------------------------------------------------------------------------------------
    def attach(self, handler) -> None:
        """Route glfw's callbacks to ``handler``'s plain methods: ``on_key(key, action, mods)``,
        ``on_mouse_button(button, action, mods)``, ``on_mouse_move(x, y)``, ``on_scroll(dx, dy)``,
        ``on_resize(width, height)`` (framebuffer pixels), ``on_focus(focused)``. Missing methods are ignored."""
        glfw = self._glfw
        self.handler = handler
        glfw.set_key_callback(self.handle, self.key_callback)
        glfw.set_mouse_button_callback(self.handle, self.mouse_button_callback)
        glfw.set_cursor_pos_callback(self.handle, self.cursor_pos_callback)
        glfw.set_scroll_callback(self.handle, self.scroll_callback)
        glfw.set_framebuffer_size_callback(self.handle, self.framebuffer_size_callback)
        glfw.set_window_focus_callback(self.handle, self.focus_callback)

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

    def focus_callback(self, window, focused):
        self._call("on_focus", bool(focused))

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
        """Destroy the window, and terminate glfw when it was the last one (safe twice).
        Release GL objects made on ``ctx`` before calling this."""
        global _open_windows
        if self._closed:
            return
        self._closed = True
        glfw = self._glfw
        glfw.destroy_window(self.handle)
        _open_windows -= 1
        if _open_windows == 0:
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
            # -noreset: the server must not reset (and drop connections) when its last client leaves
            cmd = [exe, "-displayfd", str(w), "-screen", "0", self.screen, "-nolisten", "tcp", "-noreset"]
            self.proc = subprocess.Popen(cmd, pass_fds=(w,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
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
