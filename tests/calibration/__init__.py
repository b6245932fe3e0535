"""Tests of :mod:`camsim.calibration`."""
