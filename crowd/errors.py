"""User-facing errors: one clear sentence, exit code 2, nothing half-written."""
from __future__ import annotations


class CrowdError(Exception):
    """Bad input from the user (scene file, asset, parameter). Exit code 2.

    The message is one sentence naming the file, the key (or line) and what
    would be accepted.
    """

    exit_code = 2


def printable(text: str) -> str:
    """``text`` with control characters (newlines, tabs, NUL, ...) written as escapes,
    so a key taken from a file cannot break the one-line message."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))


class SceneError(CrowdError):
    def __init__(self, path, key: str, message: str):
        self.path, self.key = str(path), key
        path, key = printable(path), printable(key)
        super().__init__(f"{path}: {key}: {message}" if key else f"{path}: {message}")


class AssetError(CrowdError):
    pass


class SimulationError(CrowdError):
    """The simulation produced NaN or Inf (named array, frame); nothing is written."""

    exit_code = 3


def user_errors() -> tuple:
    """Exceptions that are bad input, not bugs: one sentence and an exit code (2 unless the class says), never a
    traceback (``crowd.cli``, the report's and the build's tasks, the scripts)."""
    from render.context import ContextError
    from sim.errors import AssetError as SimAssetError
    from sim.params import ParamError

    return CrowdError, SimAssetError, ParamError, ContextError


#: an interrupt (Ctrl-C, SIGTERM) arrived in this process: latched, because a KeyboardInterrupt raised inside
#: third-party code can be swallowed there (a `crowd run` went on drawing for a minute after SIGINT in CI)
_interrupted = False


def on_interrupt(signum, frame):
    """Signal handler of ``crowd`` (SIGINT, SIGTERM): latch the interrupt and raise KeyboardInterrupt."""
    global _interrupted
    _interrupted = True
    raise KeyboardInterrupt


def reset_interrupt() -> None:
    """Forget a latched interrupt (a command starting: one interrupted earlier in this process is handled)."""
    global _interrupted
    _interrupted = False


def check_interrupt() -> None:
    """Raise KeyboardInterrupt when an interrupt was latched (:func:`on_interrupt`): a long loop calls this once
    per step, so an interrupt lost inside another library's code still stops it at the next one."""
    if _interrupted:
        raise KeyboardInterrupt
