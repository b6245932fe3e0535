"""Tests of :mod:`camsim.render.backends`."""
