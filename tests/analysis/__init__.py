"""Tests of :mod:`camsim.analysis`."""
