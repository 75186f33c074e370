"""GPU timer queries read with care: which elapsed times to believe on Mesa llvmpipe."""
from __future__ import annotations

#: the value some drivers (Mesa llvmpipe) return from an unusable time query
GL_TIMER_INVALID = 4294967295


def gpu_seconds(elapsed_ns, wall: float | None = None) -> float | None:
    """Seconds from a timer query's ``elapsed`` (ns), or None if implausible.

    Mesa llvmpipe's timer queries are unreliable: moderngl reads results as
    32 bits, so anything above 4.29 s (and, on llvmpipe, often the first query
    of a context) reads 4294967295; a time query combined with a samples query
    in one ``ctx.query(samples=True, time=True)`` reads a constant ~20 ns; and
    even a lone time query sometimes returns tens of nanoseconds for
    millisecond-long draws. So a reading is accepted only when it is positive,
    not the 32-bit sentinel, and -- when ``wall`` (seconds from the first
    submit to the end of ``ctx.finish``) is given -- neither larger than
    ``1.5 * wall + 1 ms`` nor smaller than 1 % of a wall time above 1 ms.
    """
    if elapsed_ns is None:
        return None
    e = int(elapsed_ns)
    if e <= 0 or e >= GL_TIMER_INVALID:
        return None
    s = e * 1e-9
    if wall is not None:
        if s > 1.5 * wall + 1e-3:
            return None
        if wall > 1e-3 and s < 0.01 * wall:
            return None
    return s
