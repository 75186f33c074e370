"""The true reference: full detail drawn with K x K samples per pixel and box-filtered down.

Every image error the project quotes is taken against this image, not against the aliased full-detail frame
(one sample per pixel): for crowds whose triangles are a fraction of a pixel the aliased frame is itself far
from what the scene looks like, so a representation closer to the true image than full detail would score as
an error against it, and one several dB worse could look fine.

**What is drawn.** The scene in LOD mode ``none`` with exact animation times (:func:`reference_scene`), its
simulation stepped exactly as any run of it (the simulation does not depend on the LOD mode or the size), the
frame selected once at K times the size (mode none depends on the size only through the aspect; the scenery and
a view-dependent terrain choose for the finer pixels).

**How.** The K x size image is drawn as tiles: a tile is an off-centre window of the frame's projection
(:func:`tile_projection`), drawn at K x K pixels per output pixel, read back and box-filtered into its block of
output pixels (:func:`box_filter`), so the full K x size image never exists. A tile is as large as the GL limits
allow (renderbuffer and viewport side; the compute rasteriser's per-pixel storage buffers, 4 bytes per pixel
through one binding) and :data:`MAX_TILE_PIXELS`; one tile covers the frame when it fits (:func:`plan_tiles`).
A tile keeps the frame's pixel scale, so the compute rasteriser's route and every pixel-size test choose as they
would on the whole K x size image.

**Filter** (:data:`FILTER`): the mean of each pixel's K x K samples on a regular grid, taken on the 8-bit output
values and rounded to the nearest.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from crowd.errors import CrowdError

#: samples per pixel along each axis: the default, and the range a setting may ask for
DEFAULT_K, MIN_K, MAX_K = 4, 2, 8
#: the filter, as reports name it
FILTER = "box filter of K x K samples per pixel (regular grid, 8-bit output values, rounded)"
#: most pixels of one tile (16 M: a 4096 x 4096 tile, ~400 MB of buffers at :data:`TILE_BYTES_PER_PIXEL`)
MAX_TILE_PIXELS = 1 << 24
#: bytes per tile pixel while a tile is drawn: colour and depth renderbuffers (4 + 4), the compute rasteriser's
#: depth and id buffers (4 + 4), the read-back (3) and its widened copy for the filter (4 x 3 = 12), rounded up
TILE_BYTES_PER_PIXEL = 32
#: bytes per output pixel held for the whole frame: the filtered image and its PNG encoding, rounded up
OUTPUT_BYTES_PER_PIXEL = 8
#: common LOD keys the reference sets away from their defaults: exact per-copy animation times
#: (``[lod] pose_rate = 0``, lod.poses: the default shares quantised poses, an error the report measures)
REFERENCE_LOD_COMMON = (("pose_rate", 0.0),)


def check_k(k, setting: str = "--reference-samples") -> int:
    """``k`` as an int in :data:`MIN_K`..:data:`MAX_K`.

    Raises
    ------
    crowd.errors.CrowdError
        One sentence naming ``setting``, the value and the range.
    """
    try:
        v = float(k)
    except (TypeError, ValueError):
        v = math.nan
    if not (math.isfinite(v) and v == int(v) and MIN_K <= v <= MAX_K):
        raise CrowdError(f"{setting} {k!r}: expected a whole number of samples per pixel along each axis from "
                         f"{MIN_K} to {MAX_K} (the reference draws K x K samples per pixel; default {DEFAULT_K})")
    return int(v)


def is_reference(scene) -> bool:
    """True when ``scene`` draws full detail as the reference does: mode none, exact pose times
    (:data:`REFERENCE_LOD_COMMON`), the other common LOD keys at their defaults (its aliased frames are the
    reference's at one sample per pixel)."""
    if scene.lod_mode != "none":
        return False
    try:
        from lod.temporal.selection import LOD_COMMON_PARAMS
    except ImportError:
        return True
    common = dict(getattr(scene, "lod_common", ()) or ())
    want = {k: p.default for k, p in LOD_COMMON_PARAMS.items()}
    want.update((k, v) for k, v in REFERENCE_LOD_COMMON if k in want)
    return all(common.get(k, LOD_COMMON_PARAMS[k].default) == v for k, v in want.items())


def reference_scene(scene):
    """``scene`` at full detail as the reference draws it: LOD mode none, no LOD keys (per-frame selection) but
    exact pose times (:data:`REFERENCE_LOD_COMMON`)."""
    extra = {}
    if any(f.name == "lod_common" for f in dataclasses.fields(scene)):
        try:
            from lod.temporal.selection import LOD_COMMON_PARAMS
        except ImportError:
            LOD_COMMON_PARAMS = {}
        extra = {"lod_common": tuple((k, v) for k, v in REFERENCE_LOD_COMMON if k in LOD_COMMON_PARAMS)}
    return dataclasses.replace(scene, lod_mode="none", lod_params=(), **extra)


# ----------------------------------------------------------------------------------------------------- tiles
@dataclass(frozen=True)
class TilePlan:
    """How a K x size reference is drawn: tiles of ``tile`` output pixels (each drawn at K x tile pixels), at
    the output corners ``origins`` (the last row and column may reach past the frame; what lies outside is
    drawn and dropped)."""

    size: tuple
    k: int
    tile: tuple
    origins: tuple

    @property
    def tile_pixels(self) -> tuple:
        """(width, height) of the framebuffer a tile is drawn into."""
        return self.k * self.tile[0], self.k * self.tile[1]

    @property
    def bytes(self) -> int:
        """Memory the drawing needs at once: one tile's buffers and the filtered frame."""
        tw, th = self.tile_pixels
        return TILE_BYTES_PER_PIXEL * tw * th + OUTPUT_BYTES_PER_PIXEL * self.size[0] * self.size[1]


def gl_limits(ctx) -> tuple:
    """(largest framebuffer side, most pixels of one framebuffer) a tile may use on ``ctx``: the renderbuffer and
    viewport limits, and the compute rasteriser's 4-byte-per-pixel storage buffers within one binding."""
    info = ctx.info
    side = min(int(info.get("GL_MAX_RENDERBUFFER_SIZE", 16384)), int(info.get("GL_MAX_TEXTURE_SIZE", 16384)),
               *[int(v) for v in (info.get("GL_MAX_VIEWPORT_DIMS") or (16384, 16384))])
    pixels = min(MAX_TILE_PIXELS, int(info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE", 1 << 27)) // 4)
    return side, pixels


def plan_tiles(size, k: int, max_side: int = 16384, max_pixels: int = MAX_TILE_PIXELS) -> TilePlan:
    """The fewest equal tiles whose K x tile framebuffer fits ``max_side`` and ``max_pixels`` (columns and rows
    added to the longer side first)."""
    w, h = int(size[0]), int(size[1])
    k = int(k)
    if max_side < k or max_pixels < k * k:
        raise ValueError(f"plan_tiles: limits {max_side} px a side, {max_pixels} px cannot hold one pixel at K={k}")
    nx = ny = 1
    while True:
        tw, th = -(-w // nx), -(-h // ny)
        if k * tw <= max_side and k * th <= max_side and (k * tw) * (k * th) <= max_pixels:
            break
        if (tw >= th and nx < w) or ny >= h:
            nx += 1
        else:
            ny += 1
    tw, th = -(-w // nx), -(-h // ny)
    origins = tuple((x, y) for y in range(0, h, th) for x in range(0, w, tw))
    return TilePlan(size=(w, h), k=k, tile=(tw, th), origins=origins)


def tile_projection(proj, size, origin, tile) -> np.ndarray:
    """(4, 4) float64: ``proj`` narrowed to the output window at ``origin`` (x right, y down, pixels) of ``tile``
    (width, height) pixels in a frame of ``size``: the window's normalised device coordinates mapped onto
    [-1, 1] by a scale and offset applied in clip space (depth untouched)."""
    w, h = float(size[0]), float(size[1])
    x0, y0 = float(origin[0]), float(origin[1])
    tw, th = float(tile[0]), float(tile[1])
    left, right = -1.0 + 2.0 * x0 / w, -1.0 + 2.0 * (x0 + tw) / w
    top, bottom = 1.0 - 2.0 * y0 / h, 1.0 - 2.0 * (y0 + th) / h
    m = np.eye(4)
    m[0, 0], m[0, 3] = 2.0 / (right - left), -(right + left) / (right - left)
    m[1, 1], m[1, 3] = 2.0 / (top - bottom), -(top + bottom) / (top - bottom)
    # clip space: x' = sx x + tx w, so that x'/w = sx (x/w) + tx
    return m @ np.asarray(proj, np.float64)


def box_filter(img: np.ndarray, k: int) -> np.ndarray:
    """(h, w, c) uint8: the rounded mean of each k x k block of ``img`` ((k h, k w, c) uint8)."""
    H, W, c = img.shape
    if H % k or W % k:
        raise ValueError(f"box_filter: image {W}x{H} is not a multiple of {k}")
    s = img.reshape(H // k, k, W // k, k, c).astype(np.uint32).sum(axis=(1, 3))
    n = k * k
    return ((s + n // 2) // n).astype(np.uint8)


def check_fits(plan: TilePlan, available: int | None, setting: str = "--reference-samples") -> None:
    """Refuse a reference whose tile and frame would not fit in ``available`` bytes (None: unknown, accepted).

    Raises
    ------
    crowd.errors.CrowdError
        One sentence naming ``setting``, the memory it needs and has, and the largest K that would fit.
    """
    from crowd.memory import MEMORY_FRACTION, human_bytes

    if available is None:
        return
    avail = MEMORY_FRACTION * float(available)
    if plan.bytes <= avail:
        return
    fits = [k for k in range(MIN_K, plan.k)
            if dataclasses.replace(plan, k=k, tile=plan.tile).bytes <= avail]
    what = f"K = {fits[-1]} would fit" if fits else \
        f"no K from {MIN_K} fits at {plan.size[0]}x{plan.size[1]}; a smaller size would"
    raise CrowdError(f"{setting} {plan.k}: the reference at {plan.size[0]}x{plan.size[1]} needs "
                     f"{human_bytes(plan.bytes)} (a {plan.tile_pixels[0]}x{plan.tile_pixels[1]} tile and the "
                     f"frame), more than the {human_bytes(avail)} available; {what}")


# ----------------------------------------------------------------------------------------------------- drawing
def draw_tiles(renderer, drawlist, plan: TilePlan, background) -> np.ndarray:
    """(h, w, 3) uint8: ``drawlist`` (selected at K x ``plan.size``) drawn tile by tile into ``renderer`` (of
    ``plan.tile_pixels``) and box-filtered down to ``plan.size``."""
    if tuple(renderer.size) != plan.tile_pixels:
        raise ValueError(f"draw_tiles: renderer of {renderer.size}, the plan's tiles are {plan.tile_pixels}")
    w, h = plan.size
    tw, th = plan.tile
    proj = np.asarray(drawlist.proj, np.float64)
    out = np.empty((h, w, 3), np.uint8)
    for x0, y0 in plan.origins:
        tile_dl = dataclasses.replace(drawlist, proj=tile_projection(proj, plan.size, (x0, y0), plan.tile)
                                      .astype(np.float32), size=plan.tile_pixels)
        renderer.draw(tile_dl, background)
        small = box_filter(renderer.read_pixels(), plan.k)
        cw, ch = min(tw, w - x0), min(th, h - y0)
        out[y0:y0 + ch, x0:x0 + cw] = small[:ch, :cw]
    return out


class TileRenderer:
    """A renderer of a reference's tiles beside one already drawing (the benchmarks: the same context, ``ctx``,
    never a second one current at once), ``reps`` uploaded; :meth:`draw` takes a DrawList selected at
    :attr:`big` and returns the filtered frame. The DrawList's pose table is not used (each copy is skinned with
    its own palette at the frame coordinate its instance row holds): exact animation times when the selection made
    none (``lod.poses`` with ``pose_rate = 0``, or a selector called without pose sharing), else the quantised ones
    it wrote.

    Parameters
    ----------
    size : (width, height) of the output
    k : samples per pixel along each axis
    ctx : the moderngl context to draw on (None: a headless one of its own)
    reps : representations to upload (the full-detail reps, statics, scenery)
    """

    def __init__(self, size, k: int = DEFAULT_K, ctx=None, reps=()):
        from render.context import create_context
        from render.renderer import Renderer

        self.size = (int(size[0]), int(size[1]))
        self._own_ctx = ctx is None
        self.ctx = create_context() if ctx is None else ctx
        self.plan = plan_tiles(self.size, check_k(k), *gl_limits(self.ctx))
        self.renderer = Renderer(self.plan.tile_pixels, ctx=self.ctx)
        self.renderer.pose_sharing = False
        for rep in reps:
            self.renderer.upload(rep)

    @property
    def big(self) -> tuple:
        """The size to select the frame at: K x the output size."""
        return self.plan.k * self.size[0], self.plan.k * self.size[1]

    def draw(self, drawlist, background=(0.1, 0.1, 0.12)) -> np.ndarray:
        """(h, w, 3) uint8: ``drawlist`` (selected at :attr:`big`) drawn in tiles and filtered."""
        return draw_tiles(self.renderer, drawlist, self.plan, background)

    def release(self) -> None:
        """Release the renderer, and the context when it is this one's own (safe twice)."""
        self.renderer.release()
        if self._own_ctx and self.ctx is not None:
            self.ctx.release()
            self.ctx = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()


class ReferenceDrawer:
    """Draws an :class:`crowd.engine.Engine`'s current state as the K x K reference.

    The engine must run its scene at full detail (:func:`reference_scene`); its renderer is replaced by one of
    the tile's framebuffer size (``Engine.open_renderer``).
    """

    def __init__(self, engine, size, k: int, limits: tuple | None = None, available: int | None = None):
        from crowd.memory import available_memory
        from render.context import create_context

        self.engine = engine
        self.size = (int(size[0]), int(size[1]))
        self.k = check_k(k)
        #: the drawer's own context (released by :meth:`close`, after the engine's renderer)
        self.ctx = create_context()
        try:
            side, pixels = gl_limits(self.ctx) if limits is None else limits
            self.plan = plan_tiles(self.size, self.k, side, pixels)
            check_fits(self.plan, available_memory() if available is None else available)
            self.renderer = engine.open_renderer(size=self.plan.tile_pixels, ctx=self.ctx)
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Release the engine's renderer and this drawer's context (safe twice)."""
        self.engine.close()
        if self.ctx is not None:
            self.ctx.release()
            self.ctx = None

    @property
    def big(self) -> tuple:
        """The size the frame is selected at: K x the output size."""
        return self.k * self.size[0], self.k * self.size[1]

    def draw(self, camera, background) -> np.ndarray:
        """(h, w, 3) uint8: the reference of the engine's current state seen by ``camera``."""
        return draw_tiles(self.renderer, self.engine.select(camera, self.big), self.plan, background)


def reference_frames(scene, frames, k: int = DEFAULT_K, limits: tuple | None = None,
                     available: int | None = None, on_frame=None) -> dict:
    """Run ``scene`` at full detail and draw the reference of each frame in ``frames``.

    Parameters
    ----------
    scene : crowd.scene.Scene (validated); drawn as :func:`reference_scene` of it at its ``[render] size``
    frames : iterable of frame indices (0-based, as ``Engine.run`` numbers them)
    k : samples per pixel along each axis (:data:`MIN_K`..:data:`MAX_K`)
    limits, available : tile limits (default: the context's, :func:`gl_limits`) and bytes available (default:
        :func:`crowd.memory.available_memory`), for tests
    on_frame : called as ``on_frame(frame, image, seconds)`` for each drawn frame (default: keep them all)

    Returns
    -------
    dict: ``images`` (frame -> (h, w, 3) uint8; empty with ``on_frame``), ``seconds`` (frame -> seconds the
    reference's selection, drawing and filtering took), ``plan`` (:class:`TilePlan`).
    """
    import time

    from crowd.engine import Engine

    want = sorted({int(f) for f in frames})
    size = tuple(scene.render.size)
    ref = reference_scene(scene).with_overrides(size=(k * size[0], k * size[1]))
    images, seconds = {}, {}
    with Engine(ref, quiet=True) as engine:
        drawer = ReferenceDrawer(engine, size, k, limits=limits, available=available)
        try:
            todo = set(want)
            for f in range(want[-1] + 1 if want else 0):
                engine.step()
                camera = engine.camera_at(engine.world.time)
                camera, _ = engine.terrain_frame(camera, drawer.renderer)  # every frame: a terrain may be temporal
                if f not in todo:
                    continue
                t0 = time.perf_counter()
                img = drawer.draw(camera, scene.render.background)
                seconds[f] = time.perf_counter() - t0
                if on_frame is not None:
                    on_frame(f, img, seconds[f])
                else:
                    images[f] = img
        finally:
            drawer.close()
    return {"images": images, "seconds": seconds, "plan": drawer.plan}
