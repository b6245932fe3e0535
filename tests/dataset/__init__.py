"""Tests of :mod:`camsim.dataset`."""
