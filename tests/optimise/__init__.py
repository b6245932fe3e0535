"""Tests of :mod:`camsim.optimise`."""
