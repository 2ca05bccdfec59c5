"""One sitting's output directory: written by one process at a time, and nothing accepted in
it is ever replaced.

:class:`SittingDirectory` creates the directory and takes its lock
(:func:`host.session.directory.lock_directory`: a second process is refused with the first
one's PID; a killed process leaves no stuck lock). A new sitting (no ``--resume``/``--redo``)
first moves the files of an earlier sitting of the unit aside, bytes unchanged, into
``DIR/earlier/SERIAL_<UTC time>/`` (:func:`host.session.directory.set_aside`), so its results
are never computed over a mix of two sittings; a record measured again (``--redo``, a second
warm-up) moves the earlier file there when the new one is saved.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path

from host.session.directory import (
    lock_directory,
    measured_order,
    read_record,
    record_names,
    record_path,
    set_aside,
    sitting_files,
)
from host.session.records import Record, RecordError


class SittingDirectory:
    """``out_dir`` for the records of ``serial``: created and locked on construction
    (DirectoryBusy when another process holds it), released by :meth:`release`. ``what``
    names this process in the lock (the command line another process is shown)."""

    def __init__(self, out_dir: Path, serial: str, what: str) -> None:
        self.out_dir = out_dir
        self.serial = serial
        out_dir.mkdir(parents=True, exist_ok=True)
        self._lock = lock_directory(out_dir, what)
        #: where this sitting moved earlier files (None: nothing moved yet)
        self.aside: Path | None = None

    def release(self) -> None:
        """Drop the lock (the files stay)."""
        self._lock.release()

    def set_aside_earlier(self) -> str | None:
        """A new sitting: move every file of an earlier sitting of this unit aside (records,
        warm-up, results, captures); the line saying where, or None when there were none."""
        files = sitting_files(self.out_dir, self.serial)
        if not files:
            return None
        self.aside = set_aside(self.out_dir, self.serial, files)
        return f"{len(files)} files of an earlier sitting moved to {self.aside}"

    def keep_earlier(self, name: str) -> tuple[Path, str | None]:
        """The path to save record ``name`` at; an earlier file there is moved aside first
        (the line saying so, else None)."""
        path = record_path(self.out_dir, self.serial, name)
        if not path.exists():
            return path, None
        self.aside = set_aside(self.out_dir, self.serial, [path], self.aside)
        return path, f"the earlier {path.name} is kept in {self.aside}"

    def read_kept(self, skip: Iterable[str], warn: Callable[[str], None]) -> dict[str, Record]:
        """Every record of this serial already in the directory but ``skip`` (``--redo``)
        that can be kept (readable, this serial) — the repeats (``x_ccw_2``, the planner's
        records) too — in the order they were measured
        (:func:`host.session.directory.measured_order`); ``warn`` is told of each that
        cannot (it is measured again)."""
        skipped = set(skip)
        kept: dict[str, Record] = {}
        for name in record_names(self.out_dir, self.serial):
            if name in skipped:
                continue
            p = record_path(self.out_dir, self.serial, name)
            try:
                rec = read_record(p)
                if rec.meta.get("serial", self.serial) != self.serial:
                    raise RecordError(f"{p}: header says serial {rec.meta['serial']!r}")
            except RecordError as exc:
                warn(f"{exc}: it will be measured again")
                continue
            kept[name] = rec
        return {n: kept[n] for n in measured_order(kept)}
