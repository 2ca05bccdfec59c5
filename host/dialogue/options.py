"""The dialogue's options: what ``python3 -m host calibrate`` (live) is told, read and checked.

:class:`DialogueOptions` holds every option of the live dialogue (units in the names: s, deg,
m), :meth:`DialogueOptions.from_args` reads them from the ``calibrate`` arguments and
:meth:`DialogueOptions.check` refuses the values and combinations that cannot work, before any
wait or any I/O with the board. :meth:`DialogueOptions.command` writes them back as the command
line that continues a session (``--resume``, ``--redo NAME``). The answers the operator types
(serial number, accumulation time, number of turns) are parsed by the same functions as the
options: :func:`parse_serial`, :func:`parse_seconds`, :func:`parse_turns`.
"""

from __future__ import annotations

import argparse
import math
import os
import shlex
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from host.board.acquisition import SAMPLE_STALL_S
from host.board.driver import STALL_S
from host.errors import UserError
from host.session.directory import Session, record_path
from host.session.inputs import parse_serial
from host.session.method import DEFAULT_HEIGHT_M, DEFAULT_LATITUDE_DEG, local_gravity
from host.session.records import RECORD_NAME_RE, STATIC_NAMES, TURN_NAMES, name_problem

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
#: pause between "get ready to turn" and the start beep, s
DEFAULT_READY_S = 2.0
#: the dialogue's plans: the method's records, the adaptive planner's, poses without a cube
#: (the planner's attitudes, or the 16 of the Earth-rate article's scheme)
PLANS = ("fixed", "adaptive", "poses", "poses16")
#: the most records the adaptive plan may add (a million ran on with no end in sight)
MAX_EXTRA = 60

# --------------------------------------------------------------------------- answers


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
    model: str = "base"  # the model to fit and ship (a host.model.spec model)
    term_files: tuple[str, ...] = ()  # Python files of custom terms for ``model``
    verify: str | None = None  # a directory of records to predict (held-out verification)
    floor: str | None = None  # --floor accel=A,gyro=G (None: measured from the records)
    thermal: str | None = None  # --thermal FILE|none (None: SERIAL_thermal.json if beside)
    noise: str | None = None  # --noise NOISE.json (the floor from the unit's noise file)
    closing: bool = True  # measure the first attitude again at the end (CLOSING_NAME)
    self_test: bool = True  # the MPU-6000 self-test first (--no-self-test: recorded not run)
    operator: str | None = None  # --operator: who measures, written in every record's header
    bench: str | None = None  # --bench: which bench, written in every record's header
    pdf: bool = False  # --pdf: also the report as SERIAL_result.pdf
    plan: str = "fixed"  # "adaptive": after the turns, the planner's records until ``target``
    #: adaptive: the worst σ/tolerance to reach — every value's standard error a twentieth of
    #: its tolerance (its 95 % interval a tenth) unless --target says otherwise
    target: float = 0.05
    max_extra: int = 12  # adaptive: at most this many records added
    #: called with (output directory, session) once the result files are written; returns the
    #: line to say (``calibrate`` archives the result there: host.cli.calibrate.archive_line)
    after_publish: Callable[[Path, Session], str] | None = None
    #: where ``calibrate`` archives the result (``after_publish``): repeated in the command
    #: that continues the session, so a resumed session is archived where the first was
    archive: str | None = None
    lot: str | None = None
    no_archive: bool = False

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
            operator=get("operator"),
            bench=get("bench"),
            pdf=bool(get("pdf", False)),
            closing=not bool(get("no_closing", False)),
            self_test=not bool(get("no_self_test", False)),
            plan=str(get("plan", "fixed")),
            target=float(get("target", 0.05)),
            max_extra=int(get("max_extra", 12)),
            after_publish=get("after_publish"),
            archive=get("archive"),
            lot=get("lot"),
            no_archive=bool(get("no_archive", False)),
        )

    def check(self) -> None:
        """Option values and combinations that cannot work -> UserError, before any wait or
        any I/O with the board (the output directory is looked at, not created)."""
        from host.model.catalogue import CATALOGUE
        from host.model.loader import load_term_file
        from host.model.spec import parse_model

        cat = dict(CATALOGUE)
        for f in self.term_files:
            cat = load_term_file(f, cat)
        parse_model(self.model, cat)  # a bad --model fails now, not after the session
        if self.plan not in PLANS:
            raise UserError(
                f"--plan {self.plan}: give fixed (the method's plan), adaptive, poses or poses16"
            )
        if not (math.isfinite(self.target) and self.target > 0.0):
            raise UserError(
                f"--target {self.target:g}: give the worst σ/tolerance to reach, e.g. 0.05"
            )
        if not 0 <= self.max_extra <= MAX_EXTRA:
            raise UserError(
                f"--max-extra {self.max_extra}: give 0 to {MAX_EXTRA} records ({MAX_EXTRA} is "
                "about an hour of the operator's time)"
            )
        for opt, name in (("--operator", self.operator), ("--bench", self.bench),
                          ("--lot", self.lot)):  # fmt: skip
            problem = None if name is None else name_problem(name)
            if problem is not None:  # was: written into every record's header and the archive
                raise UserError(f"{opt}: {problem}")
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
        unknown = [n for n in self.redo if not RECORD_NAME_RE.fullmatch(n)]
        if unknown:
            raise UserError(
                f"--redo {unknown[0]}: not a record name; use one of " + ", ".join(names)
                + " or a repeat of one (x_ccw_2)"
            )  # fmt: skip
        if self.yes and self.serial is None:
            raise UserError("--yes needs --serial (the serial number is mandatory)")
        local_gravity(self.latitude_deg, self.height_m)  # validates both
        if self.serial is not None:
            check_out_dir(self.out_dir_for(self.serial))
        if self.capture is not None and (self.capture.exists() or self.capture.is_symlink()):
            raise UserError(
                f"--capture {self.capture}: exists; a capture is never overwritten: give a new "
                "file name, or leave --capture out (the next free SERIAL_session_N.cap)"
            )
        kept = [n for n in STATIC_NAMES if n not in self._statics_to_measure()]
        if self.yes and self.static_seconds is None and self._statics_to_measure() and not kept:
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
        words = self.command_words(serial, static_seconds=static_seconds, turns=turns,
                                   port=port, then=then)  # fmt: skip
        return " ".join(shlex.quote(a) for a in words)

    def command_words(
        self,
        serial: str,
        *,
        static_seconds: float | None,
        turns: int | None,
        port: str,
        then: Sequence[str] = ("--resume",),
    ) -> list[str]:
        """The words of :meth:`command` (unquoted: what the shell passes the program)."""
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
        for opt, val in (("--operator", self.operator), ("--bench", self.bench),
                         ("--archive", self.archive), ("--lot", self.lot)):  # fmt: skip
            if val:
                args += [opt, val]
        if self.plan != "fixed":  # the resumed session plans as this one did
            args += ["--plan", self.plan, "--target", _number(self.target),
                     "--max-extra", str(self.max_extra)]  # fmt: skip
        flags = (("--no-closing", not self.closing), ("--no-self-test", not self.self_test),
                 ("--pdf", self.pdf), ("--no-archive", self.no_archive), ("--yes", self.yes),
                 ("--json", self.json))  # fmt: skip
        return [*args, *(a for a, on in flags if on), *then]


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
