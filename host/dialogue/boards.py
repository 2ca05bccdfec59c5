"""The boards of a sitting: one :class:`Unit` per board — its board, serial number, directory
and records — and what a sitting of several boards shows and decides about them.

A sitting of one board is a sitting of several with one unit: the dialogue
(:class:`host.dialogue.recorder.Recorder`) asks every question once, sends every hint to every
board, measures every record on every board at once (:func:`host.board.driver.acquire_boards`:
one start beep, each board's window on its own device time from its PONG) and keeps each
board's records in its own directory (``SERIAL/``, inside ``--out`` when given). What is shown
for several boards — one mean/std line each, each problem named by its board — is here; a
single board's screens are unchanged (:mod:`host.dialogue.screens`).

A board that leaves the sitting (its port vanished and did not come back, a failed sensor, or
the operator dropped it) is :attr:`Unit.lost`: its accepted records stay in its directory, its
own command that resumes it alone is said with where it was lost — the record, the self-test
or the start (:func:`lost_line`) — and the others go on.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from host.board.driver import Board
from host.dialogue.console import Questions
from host.dialogue.sitting import SittingDirectory
from host.session.method import record_stats
from host.session.records import Record


@dataclass(eq=False)
class Unit:
    """One board of the sitting and its unit's files: ``serial`` (empty until known), its
    output directory (locked by ``sitting``), its records kept or accepted (``done``), those
    accepted in this sitting (``accepted``) and why it left the sitting (``lost``; None: it
    is in it)."""

    board: Board
    serial: str = ""
    out_dir: Path = field(default_factory=Path)
    sitting: SittingDirectory | None = None
    done: dict[str, Record] = field(default_factory=dict)
    accepted: list[str] = field(default_factory=list)
    lost: str | None = None


class UnitsInHand:
    """The units of a sitting and the one in hand: ``board``, ``serial``, ``out_dir``,
    ``done``, ``accepted`` and ``sitting`` are those of :attr:`unit` (the first unless a step
    of every unit is taken: :meth:`_on`)."""

    units: list[Unit]
    unit: Unit

    @property
    def board(self) -> Board:
        return self.unit.board

    @board.setter
    def board(self, value: Board) -> None:
        self.unit.board = value

    @property
    def serial(self) -> str:
        return self.unit.serial

    @serial.setter
    def serial(self, value: str) -> None:
        self.unit.serial = value

    @property
    def out_dir(self) -> Path:
        return self.unit.out_dir

    @out_dir.setter
    def out_dir(self, value: Path) -> None:
        self.unit.out_dir = value

    @property
    def done(self) -> dict[str, Record]:
        return self.unit.done

    @done.setter
    def done(self, value: dict[str, Record]) -> None:
        self.unit.done = value

    @property
    def accepted(self) -> list[str]:
        return self.unit.accepted

    @property
    def sitting(self) -> SittingDirectory | None:
        return self.unit.sitting

    @sitting.setter
    def sitting(self, value: SittingDirectory | None) -> None:
        self.unit.sitting = value

    @property
    def several(self) -> bool:
        """A sitting of several boards (its screens name each board)."""
        return len(self.units) > 1

    @property
    def live(self) -> list[Unit]:
        """The units still in the sitting."""
        return [u for u in self.units if u.lost is None]

    @contextlib.contextmanager
    def _on(self, unit: Unit) -> Iterator[Unit]:
        """Take the steps inside on ``unit`` (its board, serial, records)."""
        before, self.unit = self.unit, unit
        try:
            yield unit
        finally:
            self.unit = before


#: the columns of :func:`show_means`: accel m/s², gyro °/s (the table of one board's record
#: adds the temperature)
_MEAN_COLUMNS = ("ax", "ay", "az", "gx", "gy", "gz")


def show_means(op: Questions, records: Sequence[tuple[str, Record]]) -> None:
    """Each board's static record as its mean and standard deviation per channel, one pair
    of lines per board (accel m/s², gyro °/s), under one row of channels."""
    width = max(len(s) for s, _ in records) + 1
    op.say(" " * (width + 5) + "".join(f"{c:>11}" for c in _MEAN_COLUMNS))
    for serial, rec in records:
        st = record_stats(rec)
        mean = np.concatenate([st.accel_mean, st.gyro_mean])
        std = np.concatenate([st.accel_std, st.gyro_std])
        dec = (4, 4, 4, 3, 3, 3)
        op.say(
            f"{serial:<{width}}mean "
            + "".join(f"{v:>11.{d}f}" for v, d in zip(mean, dec, strict=True))
        )
        op.say(
            " " * width
            + "std  "
            + "".join(f"{v:>11.{d + 1}f}" for v, d in zip(std, dec, strict=True))
        )


def lost_at(record: str, self_test: bool = False) -> str:
    """Where in the sitting a board left it: during the self-test (``self_test``), else at
    ``record``, the record being measured (empty: at the start, before any record)."""
    if self_test:
        return "during the self-test"
    return f"at record {record}" if record else "at the start"


def lost_line(serial: str, at: str, why: str) -> str:
    """What is said of a board that left the sitting ``at`` (:func:`lost_at`) before the
    command that resumes it alone."""
    return f"board {serial} lost {at} ({why}): its session is incomplete; resume it with:"
