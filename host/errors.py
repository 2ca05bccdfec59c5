"""Errors the user can act on. The CLI prints them as one line and exits with status 2."""


class UserError(Exception):
    """A problem the user can fix (bad file, missing port, wrong option): one clear line."""
