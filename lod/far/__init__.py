"""The far tier (issue 45): an agent whose whole body projects within a pixel or two drawn as one pre-filtered
splat, placed straight from its instance row without a traversal.

Modules in data-flow order:

- ``lod.far.footprint``: what the splat carries, measured from the character at build: covered area and mean
  lit colour by view and light direction (Wand & Straßer 2002 §3.2's stop at a pixel, §3.5's prefiltering, for
  the whole agent at once).
- ``lod.far.cache``: measured footprints on disk, content-addressed, written atomically.
- ``lod.far.rep``: ``FarRep`` (kind ``"far"``), one footprint per clip, measured in the full-detail
  representation's poses.
"""
