"""Tests of :mod:`camsim.denoise`."""
