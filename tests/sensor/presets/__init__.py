"""Tests of :mod:`camsim.sensor.presets`."""
