"""Simulation layer: characters, crowd state, systems (effects).

Knows nothing of LOD or rendering (see ../shared/ARCHITECTURE.md).
"""
