"""Replay of recorded crowds (issue 46): a recording read through PedPy (``recording``), a trajectories
placement's people as agents (``track``), and the step that moves them (``effect``), in data-flow order."""
from sim.replay.recording import FORMATS, UNITS, Recording, from_columns, load
from sim.replay.track import Track

__all__ = ["FORMATS", "UNITS", "Recording", "Track", "from_columns", "load"]
