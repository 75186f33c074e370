"""render.window: glfw window under Xvfb, blit of the renderer's frame, HUD text, font layout.

The ``display`` fixture (tests/conftest.py) starts an Xvfb server (Debian package ``xvfb``); a missing
binary fails the tests with a message saying to install it.
"""

import numpy as np
import pytest

from render.window import (FONT_FIRST, FONT_LAST, GL_VERSIONS, HUD_PADDING, FontAtlas, Hud, VirtualDisplay, Window,
                           WindowError, display_available, glyph_indices, rasterize_text)


@pytest.fixture(scope="module")
def window(display):
    w = Window((160, 120), title="test_window")
    yield w
    w.close()


@pytest.fixture(scope="module")
def atlas():
    return FontAtlas.from_pillow()


# -- font and text rasterisation (no GL) -------------------------------------------------------------------------------


def test_atlas_cells(atlas):
    n = FONT_LAST - FONT_FIRST + 1
    assert atlas.cells.shape == (n, atlas.line_height, atlas.advance) and atlas.cells.dtype == np.uint8
    assert atlas.advance >= 5 and atlas.line_height >= 10
    assert set(np.unique(atlas.cells).tolist()) == {0, 255}
    assert atlas.cells[ord("A") - FONT_FIRST].max() == 255
    assert atlas.cells[ord(" ") - FONT_FIRST].max() == 0
    # distinct glyphs look different
    assert not np.array_equal(atlas.cells[ord("O") - FONT_FIRST], atlas.cells[ord("Q") - FONT_FIRST])
    assert atlas.cells[ord("_") - FONT_FIRST][-1].max() == 0  # the last row is line spacing


def test_atlas_scale_doubles_cells(atlas):
    a2 = FontAtlas.from_pillow(scale=2)
    assert (a2.advance, a2.line_height) == (2 * atlas.advance, 2 * atlas.line_height)
    assert np.array_equal(a2.cells[:, ::2, ::2], atlas.cells)
    with pytest.raises(ValueError, match="scale"):
        FontAtlas.from_pillow(scale=0)


def test_glyph_indices_replace_unprintable():
    g = glyph_indices("A \u00e9\t~")
    q = ord("?") - FONT_FIRST
    assert g.tolist() == [ord("A") - FONT_FIRST, 0, q, q, ord("~") - FONT_FIRST]


def test_rasterize_places_cells_in_rows_and_columns(atlas):
    lh, cw = atlas.line_height, atlas.advance
    img = rasterize_text(atlas, ["AB C", "", "D"])
    assert img.shape == (3 * lh, 4 * cw)
    cell = lambda ch: atlas.cells[ord(ch) - FONT_FIRST]
    assert np.array_equal(img[:lh, :cw], cell("A"))
    assert np.array_equal(img[:lh, cw:2 * cw], cell("B"))
    assert img[:lh, 2 * cw:3 * cw].max() == 0  # the space
    assert np.array_equal(img[:lh, 3 * cw:], cell("C"))
    assert img[lh:2 * lh].max() == 0  # the empty line
    assert np.array_equal(img[2 * lh:, :cw], cell("D")) and img[2 * lh:, cw:].max() == 0
    padded = rasterize_text(atlas, ["AB C", "", "D"], padding=3)
    assert padded.shape == (3 * lh + 6, 4 * cw + 6)
    assert np.array_equal(padded[3:-3, 3:-3], img) and padded[:3].max() == 0 and padded[:, -3:].max() == 0


def test_rasterize_nothing(atlas):
    assert rasterize_text(atlas, []).shape == (0, 0)
    assert rasterize_text(atlas, ["", ""], padding=4).shape == (0, 0)
    assert rasterize_text(atlas, ["   "]).max() == 0


# -- display handling --------------------------------------------------------------------------------------------------


def test_display_available():
    assert not display_available({})
    assert display_available({"DISPLAY": ":3"})
    assert display_available({"WAYLAND_DISPLAY": "wayland-0"})


def test_window_without_display_raises(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(WindowError, match="no display"):
        Window((32, 32))


def test_virtual_display_names_the_package(monkeypatch):
    import render.window as rw

    monkeypatch.setattr(rw.shutil, "which", lambda name: None)
    with pytest.raises(FileNotFoundError, match="xvfb"):
        VirtualDisplay().start()


# -- window (Xvfb) -----------------------------------------------------------------------------------------------------


def test_window_has_a_core_context(window):
    assert window.gl_version in GL_VERSIONS
    assert window.ctx.version_code >= 330
    assert window.framebuffer_size == (160, 120)


def test_blit_copies_the_renderer_frame(window):
    from lod.drawlist import DrawList
    from render.renderer import Renderer

    size = window.framebuffer_size
    with Renderer(size, ctx=window.ctx) as r:
        dl = DrawList(origin=np.zeros(3), view=np.eye(4, dtype=np.float32), proj=np.eye(4, dtype=np.float32),
                      size=size)
        r.draw(dl, background=(0.2, 0.4, 0.6))
        window.clear((0, 0, 0))
        window.blit(r.fbo)
        px = window.read_pixels()
        assert px.shape == (size[1], size[0], 3)
        assert np.array_equal(px, r.read_pixels())
        assert np.all(np.abs(px.astype(int) - [51, 102, 153]) <= 1)


def test_hud_draws_text_and_panel(window):
    hud = Hud(window.ctx)
    try:
        size = window.framebuffer_size
        lh, cw = hud.atlas.line_height, hud.atlas.advance
        window.clear((0, 0, 0))
        assert hud.draw(["HELLO"], size, origin=(8, 8), panel=None) == (5 * cw, lh)
        px = window.read_pixels()
        # exactly the rasterised text, white on the black window, at the origin
        text = rasterize_text(hud.atlas, ["HELLO"])
        assert np.array_equal(px[8:8 + lh, 8:8 + 5 * cw, 0], text)
        assert np.array_equal(px[8:8 + lh, 8:8 + 5 * cw, 1], text)
        mask = np.ones(px.shape[:2], bool)
        mask[8:8 + lh, 8:8 + 5 * cw] = False
        assert px[mask].max() == 0  # nothing outside the text
        # with a panel: the panel darkens a grey frame around the text, and only there
        window.clear((0.5, 0.5, 0.5))
        w, h = hud.draw(["HELLO", "x"], size, origin=(8, 8))
        assert (w, h) == (5 * cw + 2 * HUD_PADDING, 2 * lh + 2 * HUD_PADDING)
        px = window.read_pixels()
        p = HUD_PADDING
        assert px[8 - p, 8 - p, 0] < 100 and px[8 + 2 * lh + p - 1, 8 + 5 * cw + p - 1, 0] < 100
        assert px[8 - p - 1, 8 - p - 1, 0] > 120 and px[-1, -1, 0] > 120
        assert (px[8:8 + lh, 8:8 + 5 * cw] == 255).all(axis=2).sum() == (text == 255).sum()
    finally:
        hud.release()
        hud.release()  # safe twice


def test_hud_grows_its_texture(window):
    hud = Hud(window.ctx)
    try:
        lines = ["x" * 100] * 20  # 600 x 240 pixels > the initial 256 x 64 texture
        w, h = hud.draw(lines, window.framebuffer_size)
        assert hud._tex_size[0] >= w >= 600 and hud._tex_size[1] >= h >= 240
        assert hud.draw([], window.framebuffer_size) == (0, 0)
    finally:
        hud.release()


class _Recorder:
    def __init__(self):
        self.calls = []

    def on_key(self, *a):
        self.calls.append(("key",) + a)

    def on_mouse_button(self, *a):
        self.calls.append(("button",) + a)

    def on_mouse_move(self, *a):
        self.calls.append(("move",) + a)

    def on_scroll(self, *a):
        self.calls.append(("scroll",) + a)

    def on_resize(self, *a):
        self.calls.append(("resize",) + a)


def test_callbacks_reach_the_handler(window):
    import glfw

    rec = _Recorder()
    window.attach(rec)
    # the functions registered with glfw are the window's callbacks
    prev = glfw.set_key_callback(window.handle, None)
    assert prev == window.key_callback
    glfw.set_key_callback(window.handle, prev)
    window.key_callback(window.handle, glfw.KEY_W, 0, glfw.PRESS, 0)
    window.mouse_button_callback(window.handle, glfw.MOUSE_BUTTON_LEFT, glfw.PRESS, 0)
    window.cursor_pos_callback(window.handle, 3, 4)
    window.scroll_callback(window.handle, 0, -1)
    assert rec.calls == [("key", glfw.KEY_W, glfw.PRESS, 0), ("button", glfw.MOUSE_BUTTON_LEFT, glfw.PRESS, 0),
                         ("move", 3.0, 4.0), ("scroll", 0.0, -1.0)]


def test_resize_reaches_the_handler(window):
    import time

    rec = _Recorder()
    window.attach(rec)
    window.set_size((200, 150))
    deadline = time.monotonic() + 5
    while not any(c[0] == "resize" for c in rec.calls) and time.monotonic() < deadline:
        window.poll()
        time.sleep(0.01)
    assert ("resize", 200, 150) in rec.calls
    assert window.framebuffer_size == (200, 150)
    window.swap()
    window.clear((1, 0, 0))
    assert window.read_pixels().shape == (150, 200, 3)
    window.set_size((160, 120))
    for _ in range(20):
        window.poll()
