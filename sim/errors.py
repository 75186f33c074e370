"""Errors the sim layer raises for bad assets or parameters.

The app (``crowd``) turns them into one-sentence messages and exit code 2.
"""
from __future__ import annotations


class AssetError(ValueError):
    """A broken or unsupported asset. The message names the file and what is wrong."""
