"""Tests of :mod:`camsim.isp`."""
