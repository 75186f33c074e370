"""Level-of-detail layer: representations of characters and per-frame selection.

Imports ``sim`` types only; produces DrawLists (plain arrays) for ``render``.
"""
