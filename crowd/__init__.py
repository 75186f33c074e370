"""The crowd application: scene schema, engine loop, CLI, telemetry, reports.

The only package that imports sim, lod and render; nothing imports it.
"""
