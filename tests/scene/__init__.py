"""Tests of :mod:`camsim.scene`."""
