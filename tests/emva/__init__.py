"""Tests of :mod:`camsim.emva`."""
