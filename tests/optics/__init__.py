"""Tests of :mod:`camsim.optics`."""
