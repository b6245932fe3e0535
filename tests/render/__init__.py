"""Tests of :mod:`camsim.render`."""
