"""Hypothesis profiles, chosen by ``HYPOTHESIS_PROFILE``: ``ci`` (the default; what ``make test`` and CI run) or
``dev`` (``make test-fast``: a fifth of the examples, for the edit–test loop). Loaded by ``tests/conftest.py``.

A test that sets its own ``max_examples`` sizes it with :func:`examples`, so that the profile scales it too.
"""

import os

from hypothesis import settings

#: The examples a test's own count is multiplied by, per profile. Unit: 1.
SCALE = {"ci": 1.0, "dev": 0.2}
PROFILE = os.environ.get("HYPOTHESIS_PROFILE", "ci")
if PROFILE not in SCALE:
    raise RuntimeError(f"HYPOTHESIS_PROFILE={PROFILE!r}: use one of {', '.join(SCALE)}")

settings.register_profile("ci", deadline=None, print_blob=True)
settings.register_profile("dev", deadline=None, max_examples=20)


def examples(n: int) -> int:
    """``n`` examples under ``ci``, a fifth of them (at least 5) under ``dev``."""
    return max(min(n, 5), round(n * SCALE[PROFILE]))


def load() -> None:
    settings.load_profile(PROFILE)
