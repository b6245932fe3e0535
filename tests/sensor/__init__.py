"""Tests of :mod:`camsim.sensor`."""
