"""Errors the user can act on. The CLI prints them as one line and exits with status 2.

Errors are told apart by their type, never by their text: code that must react to one kind of
problem catches (or tests ``isinstance``) the class below that names it, and the message stays
free to change. The hierarchy::

    UserError                   a problem the user can fix, one line (disk full, no port, …)
    ├── InputError              bad input: also a ValueError, as a program expects
    │   ├── RecordCheckError    a record fails a check of the method
    │   ├── ResultFileError     a result file that cannot be read
    │   ├── TermFileMismatch    a term file that is not the result's
    │   ├── NotDeterminedError  a result that does not determine what is asked of it
    │   └── FailedResultError   a failed result used as if it passed (exported)
    └── ResumableError          a live calibration stopped; the message says how to go on

(:class:`host.session.records.RecordError`, a record file that cannot be read, is an
``InputError`` too.)
"""

from __future__ import annotations

import errno
import os


class UserError(Exception):
    """A problem the user can fix (bad file, missing port, wrong option): one clear line."""


class InputError(UserError, ValueError):
    """Bad input given to the program or the library (a file, an argument, an option value):
    a ``ValueError`` too, so a program catches it as it would any bad value."""


class ResultFileError(InputError):
    """A calibration result file that cannot be read: not JSON, not a result, a format
    version this program does not read, a missing or bad field."""


class TermFileMismatch(InputError):
    """A term file given to run a result's custom term is not the file (by its SHA-256) the
    result was calibrated with, or a result's model needs a term file nobody gave."""


class NotDeterminedError(InputError):
    """The result does not determine a parameter that is asked of it (``apply``, ``verify``):
    the message names them and what would determine them."""


class FailedResultError(InputError):
    """A calibration that failed (values outside tolerance, not determined, held-out records
    not predicted) was to be used as if it passed (exported): refused, naming what failed and
    the option that allows it (``--allow-fail``, ``allow_fail=True``)."""


class RecordCheckError(InputError):
    """A record failed a check of the method (orientation, range, turn angle, length):
    ``file_name`` is the record file the message starts with (e.g. ``'U1_x_up.txt'``)."""

    def __init__(self, message: str, *, file_name: str) -> None:
        super().__init__(message)
        self.file_name = file_name


class ResumableError(UserError):
    """A live calibration stopped, and the message already says how to continue with the
    records accepted so far (the ``--resume`` command): nothing must be appended to it."""


class BadURLError(Exception):
    """A ``sim://`` or ``emu://`` URL option the transport refuses; the message names the option.
    A mixin: the transport raises it together with the exception type pyserial expects."""


#: what an OSError while writing means for the user
_WRITE_ERRORS = {
    errno.ENOSPC: "the disk is full",
    errno.EDQUOT: "the disk quota is exceeded",
    errno.EACCES: "permission denied",
    errno.EPERM: "permission denied",
    errno.EROFS: "the file system is read-only",
    errno.ENOENT: "no such directory",
    errno.ENOTDIR: "a file stands where its directory should be",
}


def write_error(
    path: str | os.PathLike[str] | None, exc: OSError, kept: str = "the file is unchanged"
) -> UserError:
    """A write failure as one line naming the user's file (not the hidden temp file) and what
    is ``kept`` of it."""
    what = _WRITE_ERRORS.get(exc.errno or 0, exc.strerror or str(exc))
    return UserError(f"cannot write {path or 'a file'}: {what}; {kept} ({_remedy(exc)})")


def _remedy(exc: OSError) -> str:
    """What to do about a failed write, by its cause."""
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return "free some space or choose another directory, then run again"
    if exc.errno in (errno.ENOENT, errno.ENOTDIR):
        return "create the directory or choose another one, then run again"
    if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        return "choose a directory you may write to, then run again"
    return "choose another directory, then run again"
