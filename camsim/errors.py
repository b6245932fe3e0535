"""Exception types.

:class:`CamsimError` marks a *user* error (bad input, unknown name, malformed file). The CLI prints its message
on one line and exits with status 2, with no traceback; any other exception is a bug and keeps its traceback.
"""


class CamsimError(ValueError):
    """A problem with the user's input, reported as one clear message."""
