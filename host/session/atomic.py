"""Publishing files together or not at all (records, results, reports): each is written
beside its target, fsync'ed, then renamed over it; a failure rolls the others back."""

from __future__ import annotations

import errno
import os
import tempfile
from collections.abc import Mapping
from pathlib import Path

from host.errors import write_error


def _umask() -> int:
    """The process's umask (reading it means setting it: set it straight back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_texts_atomic(files: Mapping[str | os.PathLike[str], str]) -> None:
    """Publish several UTF-8 files together or not at all.

    1. Each file is written to a temp file in its directory and fsync'ed (a full disk fails
       here, before any target is touched).
    2. Each existing target gets a hard link as its backup (a name, no data blocks).
    3. The temp files are renamed over the targets (``os.replace``, atomic per file).
    4. A failure (or an interrupt) in step 3 *rolls back* the targets already replaced: each
       is renamed back from its backup, or removed if it did not exist before. So the targets
       are either all new or all as they were, never one new beside one old.
    5. The backups are removed.

    The one window left is a power cut or ``kill -9`` in the microseconds between two renames
    of step 3; the backup ``.NAME.old-*`` files then remain beside the targets. UserError names
    the target that failed, never a hidden temp file; no temp file is left.
    """
    temps: list[tuple[str, Path]] = []  # written, not yet renamed
    backups: dict[Path, str | None] = {}  # target -> its hard-linked backup (None: a new file)
    keep: list[str] = []  # backups a failed rollback could not put back: the only old copy
    try:
        for path, text in files.items():
            p = Path(path)
            fd, tmp = _temp_beside(p)
            temps.append((tmp, p))
            _write_synced(fd, p, text)
        for _, p in temps:
            backups[p] = _backup_link(p)
        replaced: list[Path] = []
        try:
            while temps:
                tmp, p = temps[0]
                try:
                    os.replace(tmp, p)
                except OSError as exc:
                    keep = _roll_back(replaced, backups)
                    kept = "every file is unchanged" if not keep else (
                        "the old files could not all be put back; they are kept as "
                        + ", ".join(keep)
                    )  # fmt: skip
                    raise write_error(p, exc, kept) from None
                replaced.append(p)
                temps.pop(0)
        except BaseException:  # an interrupt between two renames: roll back too
            if replaced:
                keep = _roll_back(replaced, backups)
            raise
    finally:
        for tmp, _ in temps:
            _unlink_quietly(tmp)
        for backup in backups.values():
            if backup is not None and backup not in keep:
                _unlink_quietly(backup)


def _temp_beside(target: Path) -> tuple[int, str]:
    """A new hidden temp file in ``target``'s directory: (its descriptor, its name); the
    user's write error, naming ``target``, if it cannot be made."""
    try:
        return tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    except OSError as exc:
        raise write_error(target, exc) from None


def _write_synced(fd: int, target: Path, text: str) -> None:
    """Write ``text`` (UTF-8, \\n) to the temp file ``fd`` with a new file's usual mode (not
    mkstemp's private 0600) and fsync it; the user's write error names ``target``."""
    try:
        if hasattr(os, "fchmod"):
            os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
    except OSError as exc:
        raise write_error(target, exc) from None


def _backup_link(target: Path) -> str | None:
    """A hard link to ``target`` under a hidden unique name beside it (None if there is no
    target yet); raises the user's write error if the file system refuses."""
    if not target.exists():
        return None
    for k in range(100):
        backup = target.parent / f".{target.name}.old-{os.getpid()}-{k}"
        try:
            os.link(target, backup)
            return str(backup)
        except FileExistsError:
            continue
        except OSError as exc:
            raise write_error(target, exc) from None
    raise write_error(target, FileExistsError(errno.EEXIST, "cannot name a backup"))


def _roll_back(replaced: list[Path], backups: Mapping[Path, str | None]) -> list[str]:
    """Undo published renames, newest first: each target's backup renamed back over it, or a
    target that did not exist before removed. Returns the backups that could not be put back
    (empties ``replaced``)."""
    failed: list[str] = []
    while replaced:
        target = replaced.pop()
        backup = backups[target]
        try:
            if backup is None:
                os.unlink(target)
            else:
                os.replace(backup, target)
        except OSError:
            if backup is not None:
                failed.append(backup)
    return failed


def _unlink_quietly(path: str | os.PathLike[str]) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


def write_text_atomic(path: str | os.PathLike[str], text: str) -> None:
    """Write UTF-8 ``text`` to ``path`` atomically (:func:`write_texts_atomic` of one file):
    a crash or an abort never leaves a half-written file."""
    write_texts_atomic({path: text})
