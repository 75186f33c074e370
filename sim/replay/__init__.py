"""Replay of recorded crowds (issues 46, 47). Modules in data-flow order: ``recording`` (a recording read through
PedPy into sorted columns), ``cache`` (those columns kept by content, memory-mapped on later runs), ``track`` (a
trajectories placement's people as agents: position, velocity, heading at any frame, the per-frame kernel),
``effect`` (the replay step: people in and out at their recorded frames, moved after every other effect), ``feet``
(how far a replayed person's stance foot slides: the measure of the walk's fit)."""
from sim.replay.recording import FORMATS, UNITS, Recording, from_columns, load
from sim.replay.track import Track

__all__ = ["FORMATS", "UNITS", "Recording", "Track", "from_columns", "load"]
