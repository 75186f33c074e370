"""Routing (placeholder docstring)."""
