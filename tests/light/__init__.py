"""Tests of :mod:`camsim.light`."""
