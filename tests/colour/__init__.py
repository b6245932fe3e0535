"""Tests of :mod:`camsim.colour`."""
