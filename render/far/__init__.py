"""The drawer of the far tier (``lod.far``; issue 45): one pre-filtered splat per far agent, kind ``"far"``.

Modules in data-flow order:

- ``render.far.draw``: the ``Drawer``: the footprint tables lit by the frame's light, the splat pass (one
  compute dispatch per character) and the resolve that blends the far agents' coverage into the frame.
"""
