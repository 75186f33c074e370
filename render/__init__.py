"""Rendering layer: GL context, GPU resources, shaders, draws, timing, images.

Imports ``lod`` types only.
"""
