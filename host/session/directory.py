"""The record files of one session on disk: ``SERIAL_name.txt`` in one directory
(method.md §6), read and written (atomically), and which board measured them.

Nothing accepted is replaced silently: one process at a time writes a session directory
(:func:`lock_directory`, a lock a crash does not leave stuck), and the files of an earlier
sitting are moved aside, bytes unchanged, before anything would replace them
(:func:`set_aside`, into ``DIR/earlier/``).
"""

from __future__ import annotations

import contextlib
import fcntl
import math
import os
import socket
import stat
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from host.errors import UserError, write_error
from host.session.atomic import write_text_atomic
from host.session.inputs import check_serial, written_serial
from host.session.records import (
    NON_RECORD_NAMES,
    Record,
    RecordError,
    format_record,
    is_standard_name,
    parse_record_text,
)

#: record files above this size are refused: 64 MiB is ≈ 1 hour of 50 Hz rows (a record is
#: seconds to minutes), and reading holds the whole file in memory
MAX_RECORD_BYTES = 64 << 20


#: port URL schemes of boards that are not a unit: the physics simulator and the emulated APM
SIMULATED_SCHEMES = ("sim://", "emu://")
SIMULATED_BOARD = "SIMULATED BOARD"


@dataclass(frozen=True, eq=False)
class Session:
    """The records of one unit: ``serial`` and ``records`` name -> Record."""

    serial: str
    records: dict[str, Record]
    directory: Path | None = None

    def path_of(self, name: str) -> str:
        """File name used in messages, e.g. 'S1_x_up.txt'."""
        return f"{self.serial}_{name}.txt"


# ---- file names ---------------------------------------------------------------------------
def record_path(out_dir: str | os.PathLike[str], serial: str, name: str) -> Path:
    """``out_dir/SERIAL_name.txt``."""
    return Path(out_dir) / f"{serial}_{name}.txt"


def split_file_name(path: str | os.PathLike[str]) -> tuple[str, str] | None:
    """'S1_x_up.txt' -> ('S1', 'x_up'); None if the name has no '_' or is not .txt.

    Standard names (and ``x_up_2`` style repeats) are matched at the end, so a serial may hold
    underscores; otherwise the serial is the part before the first underscore.
    """
    p = Path(path)
    if p.suffix.lower() != ".txt":
        return None
    stem = p.stem
    for i in range(len(stem) - 1, 0, -1):
        if stem[i] == "_" and is_standard_name(stem[i + 1 :]):
            return stem[:i], stem[i + 1 :]
    if "_" not in stem:
        return None
    serial, name = stem.split("_", 1)
    if not serial or not name:
        return None
    return serial, name


def record_names(directory: str | os.PathLike[str], serial: str) -> list[str]:
    """The names of ``serial``'s records in ``directory``: every ``SERIAL_name.txt`` that
    :func:`read_session` reads (the repeats ``x_ccw_2`` … too; not the results or the warm-up),
    by file name."""
    d = Path(directory)
    if not d.is_dir():
        return []
    names = []
    for p in sorted(d.glob(f"{serial}_*")):
        parts = split_file_name(p)
        if parts is not None and parts[0] == serial and parts[1] not in NON_RECORD_NAMES:
            names.append(parts[1])
    return names


def sittings_in_order(records: Mapping[str, Record]) -> tuple[str, ...]:
    """The captures ``records`` name (header ``capture``: one per sitting), in the order they
    were measured: by their earliest record's ``start_time``, then name."""
    first: dict[str, str] = {}  # capture -> its earliest record start (ISO)
    for r in records.values():
        cap = r.meta.get("capture", "").strip()
        if cap:
            t = r.meta.get("start_time", "").strip() or "~"
            first[cap] = min(first.get(cap, t), t)
    return tuple(sorted(first, key=lambda c: (first[c], c)))


def measured_order(records: Mapping[str, Record]) -> list[str]:
    """The names of ``records`` in the order they were measured, from their headers: sitting
    by sitting (each sitting's capture, ``capture``, in the order of its first record's
    ``start_time``; records that name no capture last), within a sitting by ``session_s``, then
    ``start_time``, then name (a record whose header says neither keeps its name's place)."""
    captures = sittings_in_order(records)

    def key(name: str) -> tuple[int, float, str, str]:
        meta = records[name].meta
        cap = meta.get("capture", "").strip()
        try:
            s = float(meta.get("session_s", "nan"))
        except ValueError:
            s = math.nan
        sitting = captures.index(cap) if cap else len(captures)
        return (sitting, s if math.isfinite(s) else math.inf, meta.get("start_time", ""), name)

    return sorted(records, key=key)


def write_record(path: str | os.PathLike[str], record: Record) -> None:
    """Write ``record`` to ``path`` atomically (:func:`write_text_atomic`)."""
    write_text_atomic(path, format_record(record))


def _not_a_record_file(p: Path) -> str | None:
    """Why ``p`` (named like a record) cannot be read as one, or None. Never blocks (a FIFO
    is only stat'ed)."""
    try:
        st = p.stat()
    except FileNotFoundError:
        return (
            "a broken link (its target is missing)"
            if p.is_symlink()
            else "cannot read (no such file)"
        )
    except OSError as exc:
        return f"cannot read ({exc.strerror or exc})"
    if stat.S_ISDIR(st.st_mode):
        return "a directory, named like a record"
    if not stat.S_ISREG(st.st_mode):
        return "not a regular file (a device or a pipe)"
    if st.st_size > MAX_RECORD_BYTES:
        return (
            f"{st.st_size / 2**20:.0f} MiB, more than a record can be "
            f"({MAX_RECORD_BYTES >> 20} MiB ≈ 1 hour at 50 Hz)"
        )
    return None


def read_record(path: str | os.PathLike[str]) -> Record:
    """Read a record file; the name comes from the file name ``SERIAL_name.txt`` (or the
    ``# record:`` header). Raises RecordError naming the file and line."""
    p = Path(path)
    why = _not_a_record_file(p)
    if why is not None:
        raise RecordError(f"{p}: {why}; move it away or re-measure this record")
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise RecordError(f"{p}: cannot read ({exc.strerror or exc})") from exc
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RecordError(f"{p}: not a UTF-8 text file (byte {exc.start})") from exc
    parts = split_file_name(p)
    return parse_record_text(text, str(p), name=parts[1] if parts else None)


def read_session(directory: str | os.PathLike[str], serial: str | None = None) -> Session:
    """Read every ``SERIAL_name.txt`` record of one unit in ``directory``.

    ``serial`` None: inferred from the file names; several serials or none -> RecordError.
    ``SERIAL_result.txt`` is skipped.
    """
    d = Path(directory)
    if not d.is_dir():
        what = "not a directory" if d.exists() else "no such directory"
        raise RecordError(
            f"{d}: {what}; give the directory that holds the record files SERIAL_name.txt"
            " (the --out of the session that measured them)"
        )
    found: dict[str, list[tuple[str, Path]]] = {}
    for p in sorted(d.iterdir()):
        if p.name.startswith("."):
            continue
        parts = split_file_name(p)
        if parts is None or parts[1] in NON_RECORD_NAMES:
            continue
        if not p.is_file():  # a directory or a broken link named like a record: say so
            why = _not_a_record_file(p) or "not a regular file"
            raise RecordError(f"{p}: {why}; move it away (or restore the record)")
        found.setdefault(parts[0], []).append((parts[1], p))
    if serial is None:
        if not found:
            raise RecordError(f"{d}: no record files SERIAL_name.txt (e.g. S1_x_up.txt) here")
        if len(found) > 1:
            raise RecordError(
                f"{d}: records of several units ({', '.join(map(written_serial, sorted(found)))}); "
                "choose one with --serial"
            )
        serial = next(iter(found))
    try:  # the serial starts every file name and is written in the report and exports
        check_serial(serial, "the records' serial number")
    except ValueError as exc:
        raise RecordError(f"{d}: {exc}; rename the files SERIAL_name.txt") from None
    if serial not in found:
        raise RecordError(f"{d}: no records of serial {serial!r} ({serial}_x_up.txt ...)")
    records: dict[str, Record] = {}
    for name, p in found[serial]:
        rec = read_record(p)
        ms = rec.meta.get("serial")
        if ms is not None and ms != serial:
            raise RecordError(f"{p}: header says serial {ms!r}, file name says {serial!r}")
        records[name] = rec
    return Session(serial=serial, records=records, directory=d)


# ---- one writer at a time, and nothing replaced --------------------------------------------
#: the lock file in a session directory (hidden: never read as a record)
LOCK_NAME = ".imu-bench.lock"
#: the earlier sittings' files, moved aside: ``DIR/earlier/SERIAL_<UTC time>/``
EARLIER_DIR = "earlier"


class DirectoryBusy(UserError):
    """Another live process writes this session directory; the message names it (PID)."""


class DirectoryLock:
    """An exclusive ``flock`` on ``DIR/.imu-bench.lock``, which holds the owner's PID, host,
    start time and command for the message another process shows. The kernel drops the lock
    when its process ends, however it ends (``kill -9``, a crash, a power cut), so a lock is
    never left stuck: a file left behind by a dead process is taken over."""

    def __init__(self, directory: Path, fd: int) -> None:
        self.directory = directory
        self._fd: int | None = fd

    @property
    def path(self) -> Path:
        return self.directory / LOCK_NAME

    def release(self) -> None:
        """Remove the lock file and drop the lock (idempotent)."""
        fd, self._fd = self._fd, None
        if fd is None:
            return
        with contextlib.suppress(OSError):
            os.unlink(self.path)  # while still held: nobody waits on a name we remove
        os.close(fd)

    def __enter__(self) -> DirectoryLock:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.release()


def lock_directory(directory: str | os.PathLike[str], what: str = "") -> DirectoryLock:
    """Take ``directory``'s lock (the directory must exist) for this process.

    DirectoryBusy when another living process holds it, naming its PID and what it runs
    (``what``: e.g. ``calibrate --serial U17``), with what to do. A lock file whose process
    is gone (killed, crashed) holds no lock and is taken over.
    """
    d = Path(directory)
    path = d / LOCK_NAME
    for _ in range(50):  # only a remove-and-recreate race between other processes loops
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise UserError(f"{d}: cannot lock it ({exc.strerror or exc}); choose --out") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            owner = _lock_owner(fd)
            os.close(fd)
            raise DirectoryBusy(
                f"{d} is in use by another process ({owner}): two sessions writing one "
                "directory would mix their records; wait for it to end, or choose another --out"
            ) from None
        try:  # the name may have been removed (and made anew) after we opened it: retry
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if not same:
            os.close(fd)
            continue
        started = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())
        command = what or " ".join(os.path.basename(a) for a in sys.argv[:1]) or "python"
        text = f"pid {os.getpid()}\nhost {socket.gethostname()}\nsince {started}\n"
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{text}command {command}\n".encode(), 0)
        return DirectoryLock(d, fd)
    raise DirectoryBusy(f"{d}: its lock file keeps changing; choose another --out")


def _lock_owner(fd: int) -> str:
    """'PID 1234, calibrate --serial U17, since …' from a held lock file's text."""
    try:
        text = os.pread(fd, 4096, 0).decode("utf-8", "replace")
    except OSError:
        return "its PID unknown"
    info = dict(ln.split(" ", 1) for ln in text.splitlines() if " " in ln)
    parts = [f"PID {info.get('pid', '?')}"]
    if info.get("host") not in (None, socket.gethostname()):
        parts[0] += f" on {info['host']}"
    parts += [info[k] for k in ("command",) if info.get(k)]
    parts += [f"since {info['since']}"] if info.get("since") else []
    return ", ".join(parts)


def sitting_files(directory: str | os.PathLike[str], serial: str) -> list[Path]:
    """The files of ``serial``'s sitting in ``directory``: its records (the warm-up too),
    its results and its captures; not the unit's own files (``SERIAL_thermal.json``)."""
    found = []
    for p in sorted(Path(directory).glob(f"{serial}_*")):
        parts = split_file_name(p)
        if parts is not None and parts[0] == serial and p.is_file():
            found.append(p)  # records, the warm-up, SERIAL_result.txt
        elif p.name == f"{serial}_result.json" or (
            p.suffix == ".cap" and p.stem.startswith(f"{serial}_session")
        ):
            found.append(p)
    return found


def set_aside(
    directory: str | os.PathLike[str], serial: str, files: list[Path], into: Path | None = None
) -> Path:
    """Move ``files`` (of ``directory``) into ``into``, by default a new
    ``directory/earlier/SERIAL_<UTC time>/``, by renaming (the bytes are not touched); returns
    where they went. UserError naming the file that could not be moved."""
    aside = into
    if aside is None:
        stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
        base = Path(directory) / EARLIER_DIR / f"{serial}_{stamp}"
        aside, k = base, 2
        while aside.exists():
            aside, k = base.with_name(f"{base.name}_{k}"), k + 1
    try:
        aside.mkdir(parents=True, exist_ok=True)
        for p in files:
            os.rename(p, aside / p.name)
    except OSError as exc:
        raise write_error(Path(exc.filename or aside), exc, "nothing was replaced") from None
    return aside
