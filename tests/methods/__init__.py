"""Tests of :mod:`camsim.methods`."""
