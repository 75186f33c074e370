"""OpenGL context creation (headless EGL by default).

A window library (glfw, for the fly-through) creates its own context and hands
it to :class:`render.renderer.Renderer`; this module only makes the headless
one used by the engine, the tests and the benchmarks.
"""
from __future__ import annotations

#: minimum GL version required by the shaders (GLSL 330 core)
REQUIRED_GL = 330
#: Debian packages that provide a headless EGL + Mesa llvmpipe stack
EGL_PACKAGES = "libegl1 libgl1-mesa-dri"


class ContextError(RuntimeError):
    """No usable OpenGL context could be created."""


#: GL objects made through :func:`track` in this process so far (:func:`created`)
_created = 0


def created() -> int:
    """How many GL objects :func:`track` has been given in this process: a draw that makes any (a program compiled
    on first use, a buffer allocated or grown) carries a one-time cost (``DrawList.stats["gl_created"]``)."""
    return _created


def track(objects: list, obj, label: str):
    """Give GL object ``obj`` a debug label (best effort) and keep it in ``objects``, the owner's list of what
    it releases (objects without ``release()``, e.g. moderngl queries, are only labelled); returns ``obj``."""
    global _created
    _created += 1
    try:
        obj.label = label
    except Exception:  # pragma: no cover - labels are best effort
        pass
    if hasattr(obj, "release"):
        objects.append(obj)
    return obj


def release_all(objects: list) -> None:
    """Release the GL objects of ``objects`` (an owner's :func:`track` list) in reverse creation order, skipping
    any the context already released, and empty the list."""
    for o in reversed(objects):
        try:
            o.release()
        except Exception:  # pragma: no cover - released with the context
            pass
    objects.clear()


def create_context(backend: str = "egl"):
    """A standalone (headless) moderngl context.

    Parameters
    ----------
    backend : "egl" (headless, default) or None for the platform default.

    Raises
    ------
    ContextError : one sentence naming what is missing and how to install it.
    """
    import moderngl

    kwargs = {"require": REQUIRED_GL}
    if backend:
        kwargs["backend"] = backend
    try:
        return moderngl.create_standalone_context(**kwargs)
    except Exception as exc:  # moderngl/glcontext raise plain Exceptions
        raise ContextError(
            f"could not create a headless OpenGL {REQUIRED_GL // 100}.{REQUIRED_GL // 10 % 10} context with backend "
            f"{backend!r} ({exc}); install EGL and Mesa (Debian packages: {EGL_PACKAGES})"
        ) from exc


def gl_info(ctx) -> dict:
    """Renderer, vendor and version strings of a context."""
    info = ctx.info
    return {k: info.get(k) for k in ("GL_RENDERER", "GL_VENDOR", "GL_VERSION")}
