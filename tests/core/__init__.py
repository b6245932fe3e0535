"""Tests of :mod:`camsim.core`."""
