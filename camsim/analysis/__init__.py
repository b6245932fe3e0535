"""Colour analysis of rendered frames (``camsim analyze``; the docs' guide to colour at low light)."""
