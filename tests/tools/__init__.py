"""The tools under ``tools/``."""
