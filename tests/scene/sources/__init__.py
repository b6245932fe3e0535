"""Tests of :mod:`camsim.scene.sources`."""
