"""Errors the user can act on. The CLI prints them as one line and exits with status 2."""

from __future__ import annotations

import errno
import os


class UserError(Exception):
    """A problem the user can fix (bad file, missing port, wrong option): one clear line."""


#: what an OSError while writing means for the user
_WRITE_ERRORS = {
    errno.ENOSPC: "the disk is full",
    errno.EDQUOT: "the disk quota is exceeded",
    errno.EACCES: "permission denied",
    errno.EPERM: "permission denied",
    errno.EROFS: "the file system is read-only",
    errno.ENOENT: "no such directory",
}


def write_error(
    path: str | os.PathLike[str] | None, exc: OSError, kept: str = "the file is unchanged"
) -> UserError:
    """A write failure as one line naming the user's file (not the hidden temp file) and what
    is ``kept`` of it."""
    what = _WRITE_ERRORS.get(exc.errno or 0, exc.strerror or str(exc))
    return UserError(
        f"cannot write {path or 'a file'}: {what}; {kept} (free some space or choose another "
        "directory, then run again)"
    )
