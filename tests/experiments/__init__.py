"""Tests of :mod:`camsim.experiments`."""
