"""Errors a user can cause (bad file, unknown name, out-of-range value).

The CLI prints these as one line and exits non-zero; anything else is a bug and
keeps its traceback.
"""


class UserError(Exception):
    """A mistake in what the user asked for, worded for the user."""
