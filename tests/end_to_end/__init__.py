"""Whole commands as a user runs them, through several packages and real processes or readers."""
