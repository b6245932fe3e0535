"""Tests of :mod:`camsim.io`."""
