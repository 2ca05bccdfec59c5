"""The record files of one session on disk: ``SERIAL_name.txt`` in one directory
(method.md §6), read and written (atomically), and which board measured them."""

from __future__ import annotations

import os
import stat
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from host.session.atomic import write_text_atomic
from host.session.records import (
    NON_RECORD_NAMES,
    RECORD_NAME_RE,
    Record,
    RecordError,
    format_record,
    parse_record_text,
)

#: record files above this size are refused: 64 MiB is ≈ 1 hour of 50 Hz rows (a record is
#: seconds to minutes), and reading holds the whole file in memory
MAX_RECORD_BYTES = 64 << 20


#: port URL schemes of boards that are not a unit: the physics simulator and the emulated APM
SIMULATED_SCHEMES = ("sim://", "emu://")
SIMULATED_BOARD = "SIMULATED BOARD"


def simulated_ports(records: Mapping[str, Record]) -> list[str]:
    """The distinct ``port`` URLs of ``records`` that name a virtual or emulated board."""
    ports = {r.meta.get("port", "").strip() for r in records.values()}
    return sorted(p for p in ports if p.startswith(SIMULATED_SCHEMES))


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
        if stem[i] == "_" and RECORD_NAME_RE.match(stem[i + 1 :]):
            return stem[:i], stem[i + 1 :]
    if "_" not in stem:
        return None
    serial, name = stem.split("_", 1)
    if not serial or not name:
        return None
    return serial, name


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
                f"{d}: records of several units ({', '.join(sorted(found))}); "
                "choose one with --serial"
            )
        serial = next(iter(found))
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
