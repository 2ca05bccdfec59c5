"""The live calibration program (method.md §5): the dialogue with the operator on a board.

``python -m host calibrate --port PORT ...`` calls :func:`run_live_session`. This module only
asks, decides and records: the board — HELLO, commands, clock feeding, acquisition and units —
is :class:`host.board.driver.Board` (port → :class:`host.board.link.Link`, every byte into an
IMUCAP01 capture ``SERIAL_session.cap`` beside the records → frames → counts → m/s², °/s,
°C); a measurement the operator accepts becomes a :class:`host.calib.records.Record`, written
atomically as ``SERIAL_name.txt``; at the end :func:`host.calib.publish.compute_and_write`
computes and writes the results, exactly as ``calibrate --from-dir`` does.

Acquisition window, on device time: at the start beep the host sends PING; the board's PONG
gives its ``t_us`` at that moment (``device_t_us_beep``), and the measurement holds exactly the
samples whose device time lies in ``[beep, beep + duration)`` — whatever is still in flight
from before the beep is dropped by its time stamp, however the reads are chunked and however
loaded the host is. Time column: device time, ms: ``t_us`` unwrapped (32-bit wrap) minus the
``t_us`` of the first sample of the window (the device clock, not an assumed 50 Hz). Every
sample read also feeds a live minimum-delay clock estimate (:class:`host.timing.clock.LiveClock`,
restarted when the board resets); the record's ``#`` header holds the device→host mapping:
``device_t_us_start``, ``host_ns_start_beep``, ``host_ns_first_sample`` (host
``time.monotonic_ns``), and from the live estimate ``clock_host_ns_at_start`` (the first
sample's mapped host time), ``clock_skew_ppm``, ``clock_points``, ``clock_latency_median_us``,
``clock_floor_spread_us``. The session's capture file allows the best offline fit later.

Losses: sequence gaps between the frames of a measurement (frames lost on the link) plus
samples the firmware flagged MISSED are counted, reported ("3 samples lost in x_up") and
written into the record header; above :data:`LOSS_LIMIT` the program proposes to repeat.

Interruptions (decided here, the method says Ctrl+C "discards everything"):

* **Esc** aborts the measurement in progress only: nothing of it is kept, the same measurement
  is proposed again.
* **Ctrl+C** aborts the session: the measurement in progress is discarded (records are only
  written when accepted, atomically, so no half record or temp file is left). Records already
  *accepted* stay on disk, and the program prints the command that continues with
  ``--resume``. (Deleting accepted measurements would throw away operator work that cannot be
  re-done without repeating the warm-up; the method's "discards everything" is read as "nothing
  of the session in progress is used".) The capture file is kept too (complete up to the last
  read; it is not a record).
* **The board vanishes** (cable pulled: LinkLost) or **goes silent** for 2 s (LinkTimeout):
  the message appears at once, the measurement in progress is discarded, accepted records are
  kept; the port is re-opened every second (Esc/Ctrl+C give up; ``--yes`` gives up after
  :data:`YES_RECONNECT_S`) and the same measurement is proposed again.

``--resume``: records already in the output directory (and readable, same serial) are not
measured again. Without it, every measurement of the chosen stages is taken and replaces the
file of the same name when accepted; the results are computed from all of this serial's
records in the directory (so stage 2 alone reuses earlier statics, as the method allows).

Operator hints: a port with ``operator_hint`` (the ``sim://`` virtual board) is told what the
human is asked (``place`` before the placement prompt, ``turn`` at the start beep of a turn).

Length (over 600 lines): one dialogue — the §5 program with its resume, redo, reconnect, warm-up
and checks of each measurement — whose steps share the state of the sitting; the board, the
records and the results live elsewhere (host/board/driver.py, host/calib/).
"""

from __future__ import annotations

import argparse
import math
import os
import re
import shlex
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import serial

# the board driver's names, importable from here as before it moved to host/board/driver.py
from host.board.driver import HOST_SPEC_FINGERPRINT as HOST_SPEC_FINGERPRINT
from host.board.driver import IMU_FRAME_BYTES as IMU_FRAME_BYTES
from host.board.driver import PONG_TIMEOUT_S as PONG_TIMEOUT_S
from host.board.driver import SAMPLE_STALL_S as SAMPLE_STALL_S
from host.board.driver import STALL_S as STALL_S
from host.board.driver import Acquisition as Acquisition
from host.board.driver import Board as Board
from host.board.driver import BoardInfo as BoardInfo
from host.board.driver import BoardReset as BoardReset
from host.board.driver import DeferredCapture as DeferredCapture
from host.board.driver import MeasurementAborted as MeasurementAborted
from host.board.driver import SensorFault as SensorFault
from host.board.driver import default_port as default_port
from host.board.link import LinkLost, LinkTimeout
from host.calib.calibration import (
    DEFAULT_HEIGHT_M,
    DEFAULT_LATITUDE_DEG,
    build_observations,
    check_orientation,
    local_gravity,
    record_stats,
    stage1,
    trapezoid_integral,
)
from host.calib.publish import ComputeSettings, compute_and_write, show_result
from host.calib.report import verdict_line
from host.dialogue.console import Console, Questions, TerminalConsole
from host.errors import RecordCheckError, ResumableError, UserError, write_error
from host.session.checks import failed_record
from host.session.directory import (
    SIMULATED_BOARD,
    SIMULATED_SCHEMES,
    Session,
    read_record,
    read_session,
    record_path,
    write_record,
)
from host.session.records import (
    STATIC_NAMES,
    TURN_NAMES,
    WARMUP_NAME,
    Record,
    RecordError,
    turn_window_s,
)
from host.wire import sensor
from host.wire.frames import bus_meta

WARMUP_DEFAULT_S = 600.0
#: the closing check: the first static attitude measured again at the end of the session
#: (``--no-closing`` leaves it out); its difference from the opening shows the drift directly
CLOSING_NAME = f"{STATIC_NAMES[0]}_2"
DEFAULT_TURNS = 2
#: more turns than this twist the USB cable (method.md §4)
MAX_RECOMMENDED_TURNS = 3
MAX_TURNS = 10
#: above this fraction of lost samples the program proposes to repeat a measurement
LOSS_LIMIT = 0.01
#: --yes: a measurement whose default answer is "repeat" is tried at most this many times
YES_MAX_ATTEMPTS = 3
#: --yes: give up waiting for a vanished board after this many seconds
YES_RECONNECT_S = 60.0
#: pause between "get ready to turn" and the start beep, s
DEFAULT_READY_S = 2.0
SERIAL_RE = re.compile(r"^[A-Za-z0-9_-]{1,12}$")

AXIS_WORDS = {"x": "X", "y": "Y", "z": "Z"}
CHANNELS = ("Ax", "Ay", "Az", "Gx", "Gy", "Gz", "temp")


# --------------------------------------------------------------------------- small helpers


SERIAL_RULE = "1 to 12 characters: letters, digits, _ or - (it starts every file name)"


def parse_serial(text: str) -> str:
    """A serial number: 1–12 characters of A-Z a-z 0-9 _ - (it prefixes every file name).
    ValueError states the rule and what in ``text`` breaks it."""
    s = text.strip()
    if SERIAL_RE.match(s):
        return s
    if not s:
        raise ValueError(f"the serial number is mandatory: {SERIAL_RULE}")
    bad = sorted({c for c in s if not (c.isascii() and (c.isalnum() or c in "_-"))})
    why = []
    if bad:
        why.append("not allowed: " + " ".join(repr(c) for c in bad))
    if len(s) > 12:
        why.append(f"{len(s)} characters")
    raise ValueError(f"serial number {s!r} ({'; '.join(why)}): use {SERIAL_RULE}")


def parse_seconds(text: str) -> float:
    """Accumulation time per orientation, s (mandatory, 1 … 3600)."""
    try:
        v = float(text)
    except ValueError:
        raise ValueError("give the accumulation time in seconds, e.g. 30") from None
    if not math.isfinite(v) or not 1.0 <= v <= 3600.0:
        raise ValueError("the accumulation time must be between 1 and 3600 s")
    return v


def parse_turns(text: str) -> int:
    """Number of whole turns per turn record (1 … 10; more than 3 twists the cable)."""
    try:
        n = int(text)
    except ValueError:
        raise ValueError("give a whole number of turns, 1 to 3") from None
    if not 1 <= n <= MAX_TURNS:
        raise ValueError(f"the number of turns must be 1 to {MAX_TURNS} (3 or fewer recommended)")
    return n


# --------------------------------------------------------------------------- options


@dataclass
class DialogueOptions:
    """Everything the dialogue needs; units in the names (s, deg, m)."""

    port: str | None = None
    serial: str | None = None
    out: Path | None = None
    static_seconds: float | None = None
    turns: int | None = None
    warmup_s: float = WARMUP_DEFAULT_S
    latitude_deg: float = DEFAULT_LATITUDE_DEG
    height_m: float = DEFAULT_HEIGHT_M
    yes: bool = False
    json: bool = False
    resume: bool = False
    redo: tuple[str, ...] = ()
    capture: Path | None = None
    ready_s: float | None = None  # None: DEFAULT_READY_S, 0 when nobody turns (--yes, sim)
    loss_limit: float = LOSS_LIMIT
    stall_s: float = STALL_S
    sample_stall_s: float = SAMPLE_STALL_S
    hello_timeout_s: float = 5.0
    reconnect_timeout_s: float | None = None  # None: until Esc/Ctrl+C (--yes: YES_RECONNECT_S)
    model: str = "base"  # the model to fit and ship (host.modelling.model spec)
    term_files: tuple[str, ...] = ()  # Python files of custom terms for ``model``
    verify: str | None = None  # a directory of records to predict (held-out verification)
    floor: str | None = None  # --floor accel=A,gyro=G (None: measured from the records)
    thermal: str | None = None  # --thermal FILE|none (None: SERIAL_thermal.json if beside)
    noise: str | None = None  # --noise NOISE.json (the floor from the unit's noise file)
    closing: bool = True  # measure the first attitude again at the end (CLOSING_NAME)

    @classmethod
    def from_args(cls, args: argparse.Namespace | DialogueOptions) -> DialogueOptions:
        """From the ``calibrate`` arguments (missing attributes take the defaults)."""
        if isinstance(args, DialogueOptions):
            return args

        def get(name: str, default: Any = None) -> Any:
            v = getattr(args, name, None)
            return default if v is None else v

        out = get("out")
        cap = get("capture")
        return cls(
            port=get("port"),
            serial=get("serial"),
            out=Path(out) if out else None,
            static_seconds=get("static_seconds"),
            turns=get("turns"),
            warmup_s=float(get("warmup", WARMUP_DEFAULT_S)),
            latitude_deg=float(get("latitude", DEFAULT_LATITUDE_DEG)),
            height_m=float(get("height", DEFAULT_HEIGHT_M)),
            yes=bool(get("yes", False)),
            json=bool(get("json", False)),
            resume=bool(get("resume", False)),
            redo=tuple(n.strip() for r in get("redo", []) for n in r.split(",") if n.strip()),
            capture=Path(cap) if cap else None,
            ready_s=None if get("ready_seconds") is None else float(get("ready_seconds")),
            model=str(get("model", "base")),
            term_files=tuple(get("term_file", ())),
            verify=get("verify"),
            floor=get("floor"),
            thermal=get("thermal"),
            noise=get("noise"),
            closing=not bool(get("no_closing", False)),
        )

    def check(self) -> None:
        """Option values and combinations that cannot work -> UserError, before any wait or
        any I/O with the board (the output directory is looked at, not created)."""
        from host.modelling.model import CATALOGUE, load_term_file, parse_model

        cat = dict(CATALOGUE)
        for f in self.term_files:
            cat = load_term_file(f, cat)
        parse_model(self.model, cat)  # a bad --model fails now, not after the session
        if self.serial is not None:
            try:
                self.serial = parse_serial(self.serial)
            except ValueError as exc:
                raise UserError(f"--serial: {exc}") from None
        if self.static_seconds is not None:
            try:
                self.static_seconds = parse_seconds(str(self.static_seconds))
            except ValueError as exc:
                raise UserError(f"--static-seconds: {exc}") from None
        if self.turns is not None and not 1 <= self.turns <= MAX_TURNS:
            raise UserError(f"--turns must be 1 to {MAX_TURNS} (3 or fewer recommended)")
        if not math.isfinite(self.warmup_s) or self.warmup_s < 0:
            raise UserError("--warmup must be 0 (skip) or a number of seconds")
        if self.ready_s is not None and (not math.isfinite(self.ready_s) or self.ready_s < 0):
            raise UserError("--ready-seconds must be 0 or more")
        names = (*STATIC_NAMES, *TURN_NAMES, CLOSING_NAME)
        unknown = [n for n in self.redo if n not in names]
        if unknown:
            raise UserError(
                f"--redo {unknown[0]}: not a record name; use one of " + ", ".join(names)
            )
        if self.yes and self.serial is None:
            raise UserError("--yes needs --serial (the serial number is mandatory)")
        local_gravity(self.latitude_deg, self.height_m)  # validates both
        if self.serial is not None:
            check_out_dir(self.out_dir_for(self.serial))
        if self.yes and self.static_seconds is None and self._statics_to_measure():
            raise UserError(
                "--yes needs --static-seconds S, the accumulation time per static orientation "
                "(e.g. --static-seconds 30): nothing is asked with --yes"
            )

    @property
    def keeps_records(self) -> bool:
        """--resume or --redo: records already in the output directory are kept."""
        return self.resume or bool(self.redo)

    def out_dir_for(self, serial: str) -> Path:
        """The output directory: ``--out``, else a directory named after the serial number."""
        return self.out if self.out is not None else Path(serial)

    def _statics_to_measure(self) -> list[str]:
        """The static records this session will measure (all without --resume/--redo)."""
        if not self.keeps_records or self.serial is None:
            return list(STATIC_NAMES)
        out = self.out_dir_for(self.serial)
        return [
            n for n in STATIC_NAMES
            if n in self.redo or not record_path(out, self.serial, n).exists()
        ]  # fmt: skip

    def command(
        self,
        serial: str,
        *,
        static_seconds: float | None,
        turns: int | None,
        port: str,
        then: Sequence[str] = ("--resume",),
    ) -> str:
        """The ``calibrate`` command line that repeats this session's options (those given
        and those answered at the prompts) followed by ``then`` (e.g. ``--resume``); every
        word quoted for a POSIX shell (:func:`shlex.quote`), so it pastes back as it was."""
        args = ["python3", "-m", "host", "calibrate", "--port", port, "--serial", serial,
                "--out", str(self.out_dir_for(serial))]  # fmt: skip
        if static_seconds is not None:
            args += ["--static-seconds", _number(static_seconds)]
        if turns is not None:
            args += ["--turns", str(turns)]
        args += ["--warmup", _number(self.warmup_s)]
        if self.ready_s is not None:
            args += ["--ready-seconds", _number(self.ready_s)]
        if self.latitude_deg != DEFAULT_LATITUDE_DEG:
            args += ["--latitude", _number(self.latitude_deg)]
        if self.height_m != DEFAULT_HEIGHT_M:
            args += ["--height", _number(self.height_m)]
        if self.model != "base":
            args += ["--model", self.model]
        for f in self.term_files:
            args += ["--term-file", f]
        if self.verify:
            args += ["--verify", self.verify]
        for opt, val in (("--floor", self.floor), ("--thermal", self.thermal),
                         ("--noise", self.noise)):  # fmt: skip
            if val:
                args += [opt, val]
        if not self.closing:
            args += ["--no-closing"]
        args += [a for a, on in (("--yes", self.yes), ("--json", self.json)) if on]
        return " ".join(shlex.quote(a) for a in [*args, *then])


def _number(x: float) -> str:
    """``x`` as a command-line word that reads back as the same float (30, 0.5, 48.137)."""
    short = f"{x:g}"
    return short if float(short) == x else repr(float(x))


def check_out_dir(path: Path) -> None:
    """UserError unless ``path`` is, or can be created as, a writable directory."""
    if path.exists() and not path.is_dir():
        raise UserError(f"output directory {path}: exists and is not a directory; choose --out")
    probe = path
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise UserError(f"output directory {path}: {probe} is not a directory; choose --out")
    try:  # a file made and removed: os.access alone says yes to root on a read-only disk
        if not os.access(probe, os.W_OK | os.X_OK):
            raise PermissionError
        with tempfile.TemporaryFile(dir=probe):
            pass
    except OSError:
        where = "" if probe == path else f" ({probe} is not writable)"
        raise UserError(
            f"output directory {path}: cannot write there{where}; choose another --out"
        ) from None


# --------------------------------------------------------------------------- the dialogue


@dataclass
class DialogueResult:
    """What a finished dialogue produced (the records accepted in this sitting, the result)."""

    out_dir: Path
    records: list[str] = field(default_factory=list)  # accepted in this session
    result: Any = None  # host.calib.result.CalibrationResult
    files: tuple[Path, ...] = ()


class CalibrationDialogue:
    """The §5 dialogue. ``op`` asks, ``board`` measures; files go to ``opts.out``."""

    def __init__(
        self,
        opts: DialogueOptions,
        console: Console,
        port_factory: Callable[[str], serial.SerialBase] | None = None,
    ) -> None:
        self.opts = opts
        self.op = Questions(console, yes=opts.yes, idle=self._idle)
        self.board = Board(
            opts.port or "sim://",
            port_factory,
            opts.stall_s,
            self._warn,
            opts.hello_timeout_s,
            opts.sample_stall_s,
        )
        self.g = local_gravity(opts.latitude_deg, opts.height_m)
        self.serial = ""
        self.out_dir = Path()
        self.done: dict[str, Record] = {}
        self.accepted: list[str] = []
        self.turns: int | None = opts.turns
        self.static_seconds: float | None = opts.static_seconds
        self._in_idle = False
        self._session_start_ns = time.monotonic_ns()
        #: True while the warm-up runs (Ctrl+C there discards no measurement)
        self.in_warm_up = False

    # ---- plumbing ------------------------------------------------------------------------
    def _warn(self, text: str) -> None:
        self.op.say(f"!!! {text}")

    def _idle(self) -> None:
        """While waiting for the operator: keep reading the board; recover if it vanished."""
        if self._in_idle or self.board.link is None:
            return
        self._in_idle = True
        try:
            self.board.pump()
        except (LinkLost, LinkTimeout) as exc:
            self._recover(exc, measuring=False)
        finally:
            self._in_idle = False

    def _recover(self, exc: Exception, measuring: bool) -> None:
        """The board vanished or went silent: say so, re-open every second until it is back."""
        op = self.op
        op.end_progress()
        op.beep()
        op.say(f"!!! {exc}")
        if measuring:
            op.say("The measurement in progress is discarded; accepted records are kept.")
        limit = self.opts.reconnect_timeout_s
        if limit is None and self.opts.yes:
            limit = YES_RECONNECT_S
        op.say(
            "Waiting for the board to come back (trying every second"
            + ("; Esc gives up, Ctrl+C aborts)" if not self.opts.yes else ")")
        )
        start = time.monotonic()
        attempt = 0
        self._in_idle = True  # no pumping of the dead link meanwhile
        try:
            while True:
                attempt += 1
                try:
                    info = self.board.reopen()
                    break
                except UserError:
                    raise  # wrong firmware after the reconnect: nothing to wait for
                except (serial.SerialException, OSError, LinkLost, LinkTimeout):
                    pass
                if limit is not None and time.monotonic() - start > limit:
                    raise ResumableError(
                        f"the board did not come back within {limit:.0f} s; {self._resume_hint()}"
                    )
                if op.countdown(1.0, f"  waiting for the board (attempt {attempt})", False):
                    raise ResumableError(f"gave up waiting for the board; {self._resume_hint()}")
        finally:
            self._in_idle = False
        op.say(f"The board is back: {info.describe()}")

    def command(self, then: Sequence[str] = ("--resume",)) -> str:
        """This session's command line (every option given or answered) plus ``then``."""
        return self.opts.command(
            self.serial,
            static_seconds=self.static_seconds,
            turns=self.turns,
            port=self.board.url,
            then=then,
        )

    def _resume_hint(self) -> str:
        if not self.serial:
            cmd = f"python3 -m host calibrate --port {shlex.quote(self.board.url)}"
            return f"nothing was saved; start again with: {cmd}"
        n = len(self._existing_names())
        return f"{n} accepted records are kept in {self.out_dir}; continue with: {self.command()}"

    def _existing_names(self) -> list[str]:
        return [
            n for n in (*STATIC_NAMES, *TURN_NAMES, CLOSING_NAME)
            if record_path(self.out_dir, self.serial, n).exists()
        ]  # fmt: skip

    # ---- the program ---------------------------------------------------------------------
    def run(self) -> DialogueResult:
        op, opts = self.op, self.opts
        op.say("IMU CALIBRATION BENCH — MPU-6000 (APM 2.6): live calibration, method.md §5")
        op.say(
            "Ctrl+C ends the session (accepted records are kept, the command to resume is "
            "printed); Esc aborts only the current measurement"
        )
        op.say("Level the base. Connect the unit by USB (the board's green LED lights).")
        op.say(f"Opening {self.board.url} ...")
        info = self._connect()
        op.say(f"Board: {info.describe()}")
        if info.who_am_i != sensor.WHO_AM_I_MPU6000:
            self._warn(f"WHO_AM_I {info.who_am_i:#04x} is not an MPU-6000's 0x68")
        if opts.yes and not self.board.has_operator:
            self._warn("--yes on a real board: nobody is asked to place or turn the cube")

        self.serial = opts.serial or op.ask(
            "Serial number (1-12 characters: letters, digits, _ or -)", parse_serial
        )
        self.out_dir = opts.out_dir_for(self.serial)
        check_out_dir(self.out_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self._start_capture()
        self._take_stock()
        self._warm_up()

        need_static = [n for n in STATIC_NAMES if n not in self.done]
        need_turn = [n for n in TURN_NAMES if n not in self.done]
        do_static = bool(need_static)
        if need_static:
            do_static = op.yes_no(
                "Measure the 6 static orientations <Y> or go to the integral gyro calibration <N>?",
                True,
            )
        elif opts.keeps_records:
            op.say("The six static orientations are already measured (--resume).")
        if do_static:
            self._stage1(need_static)
        do_turns = bool(need_turn)
        if all(n in self.done for n in STATIC_NAMES):
            self._show_stage1()
            if need_turn and do_static:
                do_turns = op.yes_no("Integral gyro calibration <Y> or results <N>?", True)
        if not need_turn and opts.keeps_records:
            op.say("The six turns are already measured (--resume).")
        if do_turns and need_turn:
            self._stage2(need_turn)
        if opts.closing and CLOSING_NAME not in self.done and STATIC_NAMES[0] in self.done:
            self._closing_check()
        return self._results()

    def _connect(self) -> BoardInfo:
        try:
            return self.board.connect()
        except LinkTimeout as exc:
            raise UserError(str(exc)) from None

    def _start_capture(self) -> None:
        path = self.opts.capture
        if path is None:
            path = self.out_dir / f"{self.serial}_session.cap"
            k = 2
            while path.exists():
                path = self.out_dir / f"{self.serial}_session_{k}.cap"
                k += 1
        self.board.capture.start(path)
        self.op.say(f"Recording the link to {path}")

    def _take_stock(self) -> None:
        """Records of this serial already in the output directory."""
        existing = self._existing_names()
        if not existing:
            return
        if not self.opts.keeps_records:
            self._warn(
                f"{self.out_dir} already holds {len(existing)} records of {self.serial}: those "
                "measured again are replaced; the others are used for the results "
                "(--resume measures only the missing ones)"
            )
        for name in existing:
            p = record_path(self.out_dir, self.serial, name)
            try:
                rec = read_record(p)
                if rec.meta.get("serial", self.serial) != self.serial:
                    raise RecordError(f"{p}: header says serial {rec.meta['serial']!r}")
            except RecordError as exc:
                self._warn(f"{exc}: it will be measured again")
                continue
            if self.opts.keeps_records and name not in self.opts.redo:
                self.done[name] = rec
        if self.opts.redo:
            self.op.say(f"Measuring again: {', '.join(self.opts.redo)} (--redo)")
        if self.opts.keeps_records:
            self.op.say(f"Resuming: kept {', '.join(self.done) or 'nothing'}")
            kept_turns = sorted(
                r.meta["turns"]
                for n, r in self.done.items()
                if n in TURN_NAMES and "turns" in r.meta
            )
            if kept_turns:
                n_kept = int(kept_turns[0])
                if self.turns is not None and self.turns != n_kept:
                    raise UserError(
                        f"--turns {self.turns} but the kept turn records have {n_kept} turns; "
                        f"use --turns {n_kept} or delete the turn records"
                    )
                self.turns = n_kept

    def _warm_up(self) -> None:
        """The warm-up (method.md §5 step 3), recorded as ``SERIAL_warmup.txt``: one attitude,
        the chip temperature rising — the thermal calibration's first ramp
        (``python -m host thermal``). Any key skips the rest of the wait (nothing recorded)."""
        s = self.opts.warmup_s
        if s <= 0:
            return
        op = self.op
        span = f"{s / 60:.0f} minutes" if s >= 120 else f"{s:.0f} seconds"
        op.say(
            f"Keep the unit powered about {span} (warm-up; recorded for the thermal "
            "calibration)." + ("" if self.opts.yes else " Press any key when ready (skips it).")
        )

        def tick(elapsed: float, _sums: np.ndarray, _k: int) -> None:
            m, sec = divmod(int(max(s - elapsed, 0.0) + 0.999), 60)
            op.progress(f"  warm-up: {m}:{sec:02d}")

        self.in_warm_up = True  # stays set if Ctrl+C ends the session here
        try:
            acq = self.board.acquire(s, tick=tick, check_escape=op.key_pressed)
        except MeasurementAborted:
            self.in_warm_up = False
            op.end_progress()
            op.say("Warm-up ended by a key (not recorded).")
            return
        except (LinkLost, LinkTimeout, BoardReset, SensorFault) as exc:
            self.in_warm_up = False
            op.end_progress()
            self._warn(f"the warm-up is not recorded: {exc}")
            if isinstance(exc, (LinkLost, LinkTimeout)):
                self._recover(exc, measuring=False)
            return
        self.in_warm_up = False
        op.end_progress()
        if len(acq.t_us) >= 2:
            rec = self._record(WARMUP_NAME, acq, {"kind": "warmup"})
            path = record_path(self.out_dir, self.serial, WARMUP_NAME)
            write_record(path, rec)  # not a calibration record: not in self.done
            op.say(f"Warm-up done; recorded {path}")
        else:
            op.say("Warm-up done.")

    # ---- stage 1 -------------------------------------------------------------------------
    def _stage1(self, names: list[str]) -> None:
        if self.static_seconds is None:
            self.static_seconds = self.op.ask(
                "Accumulation time per orientation, seconds (typically 10 to a few hundred)",
                parse_seconds,
                option="--static-seconds",
            )
        if self.static_seconds < 10:
            self._warn(f"{self.static_seconds:g} s per orientation is short: noise averages less")
        for name in names:
            self._measure_static(name)

    def _closing_check(self) -> None:
        """The first attitude measured again (:data:`CLOSING_NAME`): the fit takes it as one
        more static record; its difference from the opening measurement is the drift over the
        session, shown here in the channels' units."""
        first = STATIC_NAMES[0]
        op = self.op
        op.say(
            f"Closing check: {first} once more (its difference from the first measurement "
            "shows the drift over the session; --no-closing leaves it out)."
        )
        if self.static_seconds is None:
            self.static_seconds = float(self.done[first].duration_s)
        self._measure_static(CLOSING_NAME)
        a, b = self.done[first], self.done[CLOSING_NAME]
        sa, sb = record_stats(a), record_stats(b)
        t = [float(r.meta.get("session_s", "nan")) for r in (a, b)]
        gap = f" {(t[1] - t[0]) / 60:.1f} min later" if all(map(math.isfinite, t)) else ""
        op.say(
            f"Closing − opening{gap}: accel "
            + " ".join(f"{v:+.4f}" for v in sb.accel_mean - sa.accel_mean)
            + " m/s², gyro "
            + " ".join(f"{v:+.4f}" for v in sb.gyro_mean - sa.gyro_mean)
            + " °/s (x y z)"
        )

    def _measure_static(self, name: str) -> None:
        op = self.op
        axis, side = name.split("_")[:2]  # x_up_2: the attitude x_up again
        assert self.static_seconds is not None
        attempts = 0
        while True:
            attempts += 1
            self.board.hint("place", name=f"{axis}_{side}")
            where = "up" if side == "up" else "down"
            op.any_key(f"Put the cube on the base with {AXIS_WORDS[axis]} {where}. Press any key.")
            acq = self._acquire(name, self.static_seconds, "Measuring")
            if acq is None:
                continue
            rec = self._record(name, acq, {"kind": "static"})
            self._show_table(rec)
            problems = self._loss_problems(name, acq)
            try:
                check_orientation(rec, record_stats(rec), self.g, f"{self.serial}_{name}.txt")
            except UserError as exc:
                problems.append(str(exc))
            if self._decide(name, problems, attempts):
                self._save(rec, problems)
                return

    def _show_stage1(self) -> None:
        stats = {n: record_stats(self.done[n]) for n in STATIC_NAMES}
        s1 = stage1(stats, self.g)
        c = s1.constants()
        op = self.op
        op.say(f"Stage 1 constants (method.md §3, g = {self.g:.5f} m/s²):")

        def line(label: str, names: Sequence[str], dec: int) -> None:
            op.say(f"  {label:<28}" + "  ".join(f"{n} {c[n]:+.{dec}f}" for n in names))

        line("accel scale errors", ("Axx", "Ayy", "Azz"), 5)
        line("accel misalignments, rad", ("Axz", "Axy", "Ayz"), 5)
        line("", ("Ayx", "Azy", "Azx"), 5)
        line("accel biases, m/s²", ("A0x", "A0y", "A0z"), 4)
        line("gyro biases, °/s", ("G0x", "G0y", "G0z"), 4)
        line("gyro g-sensitivity, (°/s)/g", ("GAxx", "GAxy", "GAxz"), 4)
        line("", ("GAyx", "GAyy", "GAyz"), 4)
        line("", ("GAzx", "GAzy", "GAzz"), 4)
        line("accel noise (std), m/s²", ("Astdx", "Astdy", "Astdz"), 4)
        line("gyro noise (std), °/s", ("Gstdx", "Gstdy", "Gstdz"), 4)
        spread = np.ptp(s1.accel_bias_estimates, axis=1)
        op.say(
            "  accel bias estimates (x, y, z pairs) disagree by "
            + ", ".join(f"{v:.4f}" for v in spread)
            + " m/s²"
        )

    # ---- stage 2 -------------------------------------------------------------------------
    def _stage2(self, names: list[str]) -> None:
        op = self.op
        if self.turns is None:
            self.turns = op.ask(
                "Number of turns per rotation (1-3; more twists the USB cable)",
                parse_turns,
                default=str(DEFAULT_TURNS),
            )
        n = self.turns
        window = turn_window_s(n)
        if n > MAX_RECOMMENDED_TURNS:
            self._warn(
                f"{n} turns: more than {MAX_RECOMMENDED_TURNS} twist the USB cable; the recording "
                f"window is 15 + 4·({n}−3) = {window:g} s"
            )
        op.say(
            f"Each turn is recorded for {window:g} s between two beeps, the same for both "
            "directions. Turn by hand about the vertical and bring the cube back to the ruler."
        )
        for name in names:
            self._measure_turn(name, n, window)

    def _measure_turn(self, name: str, n: int, window: float) -> None:
        op = self.op
        axis, direction = name.split("_")
        words = "counter-clockwise" if direction == "ccw" else "clockwise"
        attempts = 0
        while True:
            attempts += 1
            op.any_key(f"Put the cube {AXIS_WORDS[axis]} up, against the ruler. Press any key.")
            op.say(
                f"Get ready to turn {n} turn{'s' if n > 1 else ''} {words} (seen from above) "
                f"within {window:g} s, between the beeps."
            )
            ready = self.opts.ready_s
            if ready is None:  # no pause when nobody turns the cube (--yes, virtual board)
                ready = 0.0 if self.opts.yes and self.board.has_operator else DEFAULT_READY_S
            if ready > 0 and op.countdown(ready, "  start in", False):
                op.say("Aborted (Esc): nothing recorded.")
                continue
            self.board.hint("turn", axis=axis, direction=direction, turns=n, window_s=window)
            acq = self._acquire(name, window, "Turn now!")
            if acq is None:
                continue
            rec = self._record(
                name, acq, {"kind": "turn", "turns": str(n), "direction": direction,
                            "window_s": f"{window:g}"},
            )  # fmt: skip
            problems = self._loss_problems(name, acq)
            problems += self._show_turn(rec, acq, n)
            if self._decide(name, problems, attempts):
                self._save(rec, problems)
                return

    def _show_turn(self, rec: Record, acq: Acquisition, n: int) -> list[str]:
        """Show the six integrals and the range check; return the problems found."""
        assert self.board.info is not None
        op = self.op
        problems: list[str] = []
        ia = trapezoid_integral(rec.t_ms, rec.accel)
        ig = trapezoid_integral(rec.t_ms, rec.gyro)
        op.say(f"Integrals over {rec.duration_s:.2f} s (trapezoid rule):")
        op.say(
            "  " + "  ".join(f"∫{c} {v:+10.4f} m/s" for c, v in zip(CHANNELS[:3], ia, strict=True))
        )
        op.say(
            "  " + "  ".join(f"∫{c} {v:+10.3f} °" for c, v in zip(CHANNELS[3:6], ig, strict=True))
        )
        gyro_counts = np.abs(acq.counts[:, 4:7]) if len(acq.counts) else np.zeros((0, 3))
        limit = self.board.info.gyro_alarm_counts
        over = int(np.count_nonzero(np.any(gyro_counts >= limit, axis=1)))
        peak = float(np.abs(rec.gyro).max()) if len(rec) else 0.0
        if over:
            op.beep()
            op.beep()
            msg = (
                f"RANGE ALARM: {over} gyro samples at or beyond ±{self.board.info.gyro_range_dps} "
                f"°/s (peak {peak:.1f} °/s): the turn was too fast, turn more slowly"
            )
            problems.append(msg)  # shown once, with the question (_decide)
        else:
            op.say(
                f"  peak rate {peak:.1f} °/s (working range ±{self.board.info.gyro_range_dps} °/s)"
            )
        fname = f"{self.serial}_{rec.name}.txt"
        try:
            check_orientation(rec, record_stats(rec), self.g, fname)
        except RecordCheckError as exc:
            problems.append(str(exc))
        statics = {k: v for k, v in self.done.items() if k in STATIC_NAMES}
        if statics and not over:  # the engine's angle check, with the statics' bias
            sess = Session(self.serial, {**statics, rec.name: rec}, self.out_dir)
            try:
                build_observations(sess, self.g, turns=n, latitude_deg=self.opts.latitude_deg)
            except RecordCheckError as exc:
                if exc.file_name == fname:  # a problem of this record, not of the statics
                    problems.append(str(exc))
            except UserError:
                pass
        return problems

    # ---- one measurement -----------------------------------------------------------------
    def _acquire(self, name: str, seconds: float, title: str) -> Acquisition | None:
        """Beep, record ``seconds`` of device time with a progress line, beep. None when the
        measurement was aborted (Esc) or the board vanished/restarted (recovered)."""
        op = self.op
        board = self.board
        assert board.info is not None
        info = board.info
        op.beep()
        op.say(f"{title} {name}: {seconds:g} s" + ("" if self.opts.yes else " (Esc aborts)"))
        a_scale = sensor.G0 / info.accel_lsb_per_g
        g_scale = 1.0 / sensor.GYRO_LSB_PER_DPS[info.gyro_fs_sel]
        up_axis = "xyz".index(name[0])
        # for a turn: the angle turned so far about the up axis, from the mean rate between
        # two ticks (rough: the bias is not removed), shown to help the operator
        last = {"t": 0.0, "k": 0, "sum": 0.0, "angle": 0.0}

        def tick(elapsed: float, sums: np.ndarray, k: int) -> None:
            frac = min(1.0, elapsed / seconds) if seconds > 0 else 1.0
            bar = "#" * int(frac * 10) + "-" * (10 - int(frac * 10))  # means fit 80 columns
            head = f"{name} [{bar}] {elapsed:6.1f}/{seconds:g} s"
            if k == 0:
                op.progress(head)
                return
            m = sums / k
            if name.endswith(("_ccw", "_cw")):
                s_up = float(sums[4 + up_axis])
                if k > last["k"]:
                    rate = (s_up - last["sum"]) / (k - last["k"]) * g_scale
                    last["angle"] += rate * (elapsed - last["t"])
                last.update(t=elapsed, k=k, sum=s_up)
                op.progress(f"{head}  turned {last['angle']:+5.0f}° about {name[0].upper()}")
            else:
                op.progress(
                    f"{head}  A "
                    + " ".join(f"{v * a_scale:+.3f}" for v in m[0:3])
                    + "  G "
                    + " ".join(f"{v * g_scale:+.3f}" for v in m[4:7])
                )

        try:
            acq = board.acquire(seconds, tick=tick, check_escape=op.escape_pressed)
        except MeasurementAborted:
            op.end_progress()
            op.beep()
            op.say(f"Measurement of {name} aborted (Esc): nothing kept. Again:")
            return None
        except (LinkLost, LinkTimeout) as exc:
            self._recover(exc, measuring=True)
            op.say(f"Measuring {name} again.")
            return None
        except BoardReset as exc:
            op.end_progress()
            self._warn(f"{exc}: the measurement of {name} is discarded; measuring it again")
            return None
        except SensorFault as exc:
            op.end_progress()
            op.beep()
            self._warn(f"{exc}")
            self._warn(f"the measurement of {name} is discarded")
            if self.opts.yes or not op.yes_no("Measure again <Y> or stop <N>?", True):
                raise ResumableError(f"{name}: {exc}; {self._resume_hint()}") from None
            return None
        op.end_progress()
        op.beep()
        if len(acq.t_us) < 2:
            self._warn(f"no samples received for {name}; measuring it again")
            return None
        return acq

    def _record(self, name: str, acq: Acquisition, extra: dict[str, str]) -> Record:
        assert self.board.info is not None
        accel, gyro, temp = self.board.physical(acq.counts)
        meta: dict[str, str] = {"serial": self.serial, **extra}
        meta.update(self.board.info.meta())
        meta.update(
            {
                "start_time": acq.start_time,
                "samples": str(len(acq.t_us)),
                "lost_frames": str(acq.lost_frames),
                "missed_samples": str(acq.missed),
                "lost_percent": f"{100 * acq.loss_fraction:.3f}",
                "crc_errors": str(acq.crc_errors),
                "device_t_us_start": str(acq.start_t_us),
                "device_t_us_beep": str(acq.beep_t_us),
                **self._session_time(acq),
                "host_ns_start_beep": str(acq.beep_ns),
                "host_ns_first_sample": str(acq.first_ns),
                "time_mapping": "device_t_us_start (first sample) at host_ns_start_beep "
                "(time.monotonic_ns of the start beep); clock_*: live minimum-delay map",
                **self.board.clock_meta(acq.start_t_us),
                **bus_meta(acq.status_flags),
                "port": self.board.url,
                **(
                    {"board": f"{SIMULATED_BOARD} {self.board.url}"}
                    if self.board.url.startswith(SIMULATED_SCHEMES)
                    else {}
                ),
                "capture": self.board.capture.path.name,
                "program": "python -m host calibrate (live)",
            }
        )
        return Record(name, acq.t_us / 1000.0, accel, gyro, temp, meta)

    def _session_time(self, acq: Acquisition) -> dict[str, str]:
        """Record start time: ``power_on_s`` (device clock since the board's last reset,
        unwrapped; the workbench's time since power-on) and ``session_s`` (host monotonic
        clock since the program started), both s, as :data:`host.records.TIME_KEYS` says."""
        out = {"session_s": f"{(acq.beep_ns - self._session_start_ns) / 1e9:.3f}"}
        p = self.board.power_on_s(acq.start_t_us)
        if p is not None:
            out["power_on_s"] = f"{p:.3f}"
        return out

    def _show_table(self, rec: Record) -> None:
        st = record_stats(rec)
        mean = np.concatenate([st.accel_mean, st.gyro_mean, [rec.temp.mean()]])
        std = np.concatenate([st.accel_std, st.gyro_std, [rec.temp.std(ddof=1)]])
        op = self.op
        op.say(f"{rec.name}: {len(rec)} samples over {rec.duration_s:.2f} s")
        op.say("      " + "".join(f"{c:>10}" for c in CHANNELS))
        dec = (4, 4, 4, 3, 3, 3, 1)
        op.say("mean  " + "".join(f"{v:>10.{d}f}" for v, d in zip(mean, dec, strict=True)))
        op.say("std   " + "".join(f"{v:>10.{d + 1}f}" for v, d in zip(std, dec, strict=True)))

    def _loss_problems(self, name: str, acq: Acquisition) -> list[str]:
        if acq.lost == 0:
            return []
        self.op.say(
            f"{acq.lost} samples lost in {name} ({acq.lost_frames} frames lost on the link, "
            f"{acq.missed} missed by the firmware; {100 * acq.loss_fraction:.2f} %)"
        )
        if acq.loss_fraction > self.opts.loss_limit:
            return [
                f"{100 * acq.loss_fraction:.1f} % of the samples of {name} were lost "
                f"(limit {100 * self.opts.loss_limit:g} %)"
            ]
        return []

    def _decide(self, name: str, problems: list[str], attempts: int) -> bool:
        """Save (True) or repeat (False). With problems the default is to repeat."""
        op = self.op
        if not problems:
            return op.yes_no("Save <Y> or repeat <N>?", True)
        for p in problems:
            op.say(f"!!! {p}")
        if self.opts.yes and attempts >= YES_MAX_ATTEMPTS:
            raise ResumableError(
                f"{name}: still wrong after {attempts} attempts ({problems[0]}); "
                + self._resume_hint()
            )
        return not op.yes_no("Repeat <Y> or save anyway <N>?", True)

    def _save(self, rec: Record, problems: Sequence[str] = ()) -> None:
        """Write the accepted record; one kept despite ``problems`` carries them in its
        header (``warning``), and the report lists it with them."""
        if problems:
            rec.meta["warning"] = " ".join("; ".join(problems).split())
        path = record_path(self.out_dir, self.serial, rec.name)
        write_record(path, rec)
        self.done[rec.name] = rec
        self.accepted.append(rec.name)
        self.op.say(f"Saved {path}")

    # ---- results -------------------------------------------------------------------------
    def _results(self) -> DialogueResult:
        """Compute and write the results from every record of this serial in the output
        directory (:func:`host.calib.publish.compute_and_write`, as ``calibrate --from-dir``)."""
        op = self.op
        missing = [
            n for n in STATIC_NAMES if not record_path(self.out_dir, self.serial, n).exists()
        ]
        if missing:
            raise ResumableError(
                f"the results need the six static records; missing {', '.join(missing)}; "
                + self._resume_hint()
            )
        session = read_session(self.out_dir, self.serial)
        settings = ComputeSettings(
            latitude_deg=self.opts.latitude_deg,
            height_m=self.opts.height_m,
            model=self.opts.model,
            term_files=self.opts.term_files,
            floor=self.opts.floor,
            verify=self.opts.verify,
            thermal=self.opts.thermal,
            noise_file=self.opts.noise,
        )
        try:
            pub = compute_and_write(session, self.out_dir, settings, note=op.say)
        except RecordCheckError as exc:
            name = failed_record(exc, self.serial)
            if name is None:
                raise
            raise ResumableError(
                f"{exc}; measure {name} again (the other records are kept) with: "
                + self.command(then=("--redo", name))
            ) from None
        op.say(f"Results: {pub.report_path} and {pub.json_path}")
        show_result(pub.result, self.opts.json)
        op.say(verdict_line(pub.result, pub.report_path))  # the last line on screen
        return DialogueResult(
            self.out_dir, list(self.accepted), pub.result, (pub.report_path, pub.json_path)
        )


# --------------------------------------------------------------------------- entry points


def run_dialogue(
    args: argparse.Namespace | DialogueOptions,
    console: Console | None = None,
    port_factory: Callable[[str], serial.SerialBase] | None = None,
) -> int:
    """Run the live calibration dialogue; the runner of ``python -m host calibrate --port``.

    ``args``: the parsed ``calibrate`` arguments (``python -m host calibrate``) or a
    :class:`DialogueOptions`. ``console``: the terminal (default: the real one; tests pass a
    :class:`host.operator.ScriptedConsole`). ``port_factory(url)``: opens the port (default
    :func:`host.link.open_port`). Returns the exit status: 0 every value within tolerance,
    1 some outside, 130 aborted with Ctrl+C. UserError for what the user can fix.
    """
    opts = DialogueOptions.from_args(args)
    opts.check()
    note = None
    if not opts.port:
        opts.port, note = default_port()
        if opts.port == "sim://" and opts.yes:  # nobody watches: as fast as it computes
            opts.port = "sim://?speed=max"
            note = f"{note}; at full speed with --yes (--port sim:// shows it in real time)"
    own = console is None
    term = TerminalConsole(interactive=not opts.yes) if own else None
    con: Console = term if term is not None else console  # type: ignore[assignment]
    if term is not None:
        term.open()
    session: CalibrationDialogue | None = None
    try:
        if note:
            con.say(note)
        session = CalibrationDialogue(opts, con, port_factory)
        outcome = session.run()
        return 0 if outcome.result is not None and outcome.result.all_passed else 1
    except KeyboardInterrupt:
        con.end_progress()
        con.say("")
        con.say(
            "Aborted (Ctrl+C) during the warm-up (not recorded)."
            if session is not None and session.in_warm_up
            else "Aborted (Ctrl+C): the measurement in progress is discarded."
        )
        if session is not None and session.serial:
            con.say(session._resume_hint())
        return 130
    except (UserError, OSError) as exc:
        # a session ending on an error (disk full, sensor failed, board gone) always says how
        # to continue with the records already accepted
        told = isinstance(exc, ResumableError)  # the message already says how to continue
        if session is None or not session.serial or told:
            raise
        text = str(exc) if isinstance(exc, UserError) else str(write_error(exc.filename, exc))
        raise UserError(f"{text}; {session._resume_hint()}") from None
    finally:
        if session is not None:
            session.board.close()
        if term is not None:
            term.close()


# the names before "session" got its one meaning (the records of one sitting, README "Words");
# kept for code written against them
SessionOptions = DialogueOptions
SessionResult = DialogueResult
LiveSession = CalibrationDialogue
run_live_session = run_dialogue
