"""Colour analysis of rendered frames (MODEL.md §6)."""
