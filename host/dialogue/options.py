"""The dialogue's options: what ``python3 -m host calibrate`` (live) is told, read and checked.

:class:`DialogueOptions` holds every option of the live dialogue (units in the names: s, deg,
m) in its parts — the session's files (:class:`SessionFiles`), what is measured for how long
(:class:`Schedule`), the plan (:class:`Planning`), how the result is computed
(:class:`host.calib.publish.ComputeSettings`), who measures where and the archive
(:class:`Provenance`), the link's limits (:class:`LinkLimits`); ``calibrate`` builds them from
its arguments (:func:`host.cli.calibrate.dialogue_options`) and
:meth:`DialogueOptions.check` refuses the values and combinations that cannot work, before any
wait or any I/O with the board. :meth:`DialogueOptions.command` writes them back as the command
line that continues a session (``--resume``, ``--redo NAME``). The answers the operator types
(serial number, accumulation time, number of turns) are parsed by the same functions as the
options: :func:`parse_serial`, :func:`parse_seconds`, :func:`parse_turns`.
"""

from __future__ import annotations

import math
import os
import shlex
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from host.board.acquisition import SAMPLE_STALL_S
from host.board.driver import STALL_S
from host.calib.certificate import FROM_OPTIONS
from host.calib.decision import DEFAULT_RULE
from host.calib.publish import ComputeSettings
from host.errors import UserError
from host.session.directory import record_path
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


@dataclass(frozen=True)
class SessionFiles:
    """Which unit, where its files go and what of an earlier sitting is kept: ``serial``
    (None: asked), ``out`` (None: a directory named after the serial), ``capture`` (None: the
    next free ``OUT/SERIAL_session.cap``), ``resume`` (keep every record there), ``redo`` (the
    records measured again, the others kept)."""

    serial: str | None = None
    out: Path | None = None
    capture: Path | None = None
    resume: bool = False
    redo: tuple[str, ...] = ()


@dataclass(frozen=True)
class Schedule:
    """What is measured and for how long, s: ``static_seconds`` per static record and
    ``turns`` per turn record (None: asked), the warm-up, the pause before a turn's start
    beep (None: :data:`DEFAULT_READY_S`, 0 when nobody turns: ``--yes`` on ``sim://``), the
    closing check (:data:`CLOSING_NAME`) and the MPU-6000's self-test first."""

    static_seconds: float | None = None
    turns: int | None = None
    warmup_s: float = WARMUP_DEFAULT_S
    ready_s: float | None = None
    closing: bool = True
    self_test: bool = True


@dataclass(frozen=True)
class Planning:
    """``plan``: "fixed" (the method's records) or "adaptive" (after the turns, the planner's
    records until ``target``, the worst σ/tolerance — every value's standard error a
    twentieth of its tolerance, its 95 % interval a tenth, unless --target says otherwise —
    with at most ``max_extra`` records added)."""

    plan: str = "fixed"
    target: float = 0.05
    max_extra: int = 12


@dataclass(frozen=True)
class Provenance:
    """Who measures on which bench (every record's header and the archive), the production
    lot, and where ``calibrate`` archives the result (``archive``: None the default one;
    ``no_archive``: not at all) — repeated in the command that continues the session, so a
    resumed session is archived where the first was."""

    operator: str | None = None
    bench: str | None = None
    lot: str | None = None
    archive: str | None = None
    no_archive: bool = False


@dataclass(frozen=True)
class LinkLimits:
    """How much the link may lose and how long it may stall, s: above ``loss_limit`` (a
    fraction of the samples) a measurement is proposed again; ``reconnect_timeout_s`` None:
    wait for a vanished board until Esc/Ctrl+C (``--yes``: YES_RECONNECT_S)."""

    loss_limit: float = LOSS_LIMIT
    stall_s: float = STALL_S
    sample_stall_s: float = SAMPLE_STALL_S
    hello_timeout_s: float = 5.0
    reconnect_timeout_s: float | None = None


@dataclass(frozen=True)
class DialogueOptions:
    """Everything the dialogue needs, in its parts: the port (None: the first board found,
    else ``sim://``), ``yes`` (nothing asked), ``json`` (the result as JSON on stdout), the
    session's files, its schedule, its plan, how the result is computed (the same settings
    as ``calibrate --from-dir``: :class:`host.calib.publish.ComputeSettings`), its provenance
    and the link's limits."""

    port: str | None = None
    yes: bool = False
    json: bool = False
    #: the other boards of a sitting of several, (port, serial) each after ``port`` and
    #: ``files.serial`` (empty: a sitting of one board)
    more_boards: tuple[tuple[str, str], ...] = ()
    files: SessionFiles = field(default_factory=SessionFiles)
    schedule: Schedule = field(default_factory=Schedule)
    planning: Planning = field(default_factory=Planning)
    compute: ComputeSettings = field(default_factory=ComputeSettings)
    provenance: Provenance = field(default_factory=Provenance)
    link: LinkLimits = field(default_factory=LinkLimits)

    def check(self) -> DialogueOptions:
        """These options with the serial number and the accumulation time as parsed; option
        values and combinations that cannot work -> UserError, before any wait or any I/O
        with the board (the output directory is looked at, not created)."""
        _check_model(self.compute)
        _check_planning(self.planning)
        _check_names(self.provenance)
        files, schedule = _checked_serial(self.files), _checked_schedule(self.schedule)
        _check_redo(files, self.yes)
        checked = replace(self, files=files, schedule=schedule,
                          more_boards=_checked_boards(self, files))  # fmt: skip
        local_gravity(self.compute.latitude_deg, self.compute.height_m)  # validates both
        checked._check_files()
        return checked

    def _check_files(self) -> None:
        """The output directory writable, the capture new, and --yes not waiting on an answer
        for the accumulation time."""
        f = self.files
        for serial in (f.serial, *(s for _, s in self.more_boards)):
            if serial is not None:
                check_out_dir(self.out_dir_for(serial))
        if f.capture is not None and (f.capture.exists() or f.capture.is_symlink()):
            raise UserError(
                f"--capture {f.capture}: exists; a capture is never overwritten: give a new "
                "file name, or leave --capture out (the next free SERIAL_session_N.cap)"
            )
        measured = self._statics_to_measure()
        kept = [n for n in STATIC_NAMES if n not in measured]
        if self.yes and self.schedule.static_seconds is None and measured and not kept:
            raise UserError(
                "--yes needs --static-seconds S, the accumulation time per static orientation "
                "(e.g. --static-seconds 30): nothing is asked with --yes"
            )

    @property
    def keeps_records(self) -> bool:
        """--resume or --redo: records already in the output directory are kept."""
        return self.files.resume or bool(self.files.redo)

    def out_dir_for(self, serial: str) -> Path:
        """The output directory: ``--out``, else a directory named after the serial number;
        in a sitting of several boards each board's is ``SERIAL/`` inside ``--out``."""
        if self.more_boards and self.files.out is not None:
            return self.files.out / serial
        return self.files.out if self.files.out is not None else Path(serial)

    def alone(self, serial: str, port: str, out_dir: Path) -> DialogueOptions:
        """These options for one board of a sitting on its own (the command that resumes a
        board that left the sitting)."""
        files = replace(self.files, serial=serial, out=out_dir)
        return replace(self, port=port, more_boards=(), files=files)

    @property
    def ports(self) -> tuple[str, ...]:
        """Every port of the sitting, the first board's first."""
        return (self.port or "sim://", *(p for p, _ in self.more_boards))

    def _statics_to_measure(self) -> list[str]:
        """The static records this session will measure (all without --resume/--redo)."""
        serial = self.files.serial
        if not self.keeps_records or serial is None:
            return list(STATIC_NAMES)
        out = self.out_dir_for(serial)
        return [
            n for n in STATIC_NAMES
            if n in self.files.redo or not record_path(out, serial, n).exists()
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
        """The words of :meth:`command` (unquoted: what the shell passes the program); a
        sitting of several boards names each board's port and serial, and ``--out`` as given."""
        args = ["python3", "-m", "host", "calibrate", "--port", port, "--serial", serial]
        for other_port, other_serial in self.more_boards:
            args += ["--port", other_port, "--serial", other_serial]
        if not self.more_boards or self.files.out is not None:
            args += ["--out", str(self.files.out if self.more_boards else self.out_dir_for(serial))]
        if static_seconds is not None:
            args += ["--static-seconds", _number(static_seconds)]
        if turns is not None:
            args += ["--turns", str(turns)]
        args += _schedule_words(self.schedule)
        args += _compute_words(self.compute)
        args += _provenance_words(self.provenance)
        if self.planning.plan != "fixed":  # the resumed session plans as this one did
            p = self.planning
            args += ["--plan", p.plan, "--target", _number(p.target),
                     "--max-extra", str(p.max_extra)]  # fmt: skip
        flags = (("--no-closing", not self.schedule.closing),
                 ("--no-self-test", not self.schedule.self_test),
                 ("--pdf", self.compute.pdf), ("--no-archive", self.provenance.no_archive),
                 ("--yes", self.yes), ("--json", self.json))  # fmt: skip
        return [*args, *(a for a, on in flags if on), *then]


def _check_model(compute: ComputeSettings) -> None:
    """A bad --model (or term file) fails now, not after the session."""
    from host.model.catalogue import CATALOGUE
    from host.model.loader import load_term_file
    from host.model.spec import parse_model

    cat = dict(CATALOGUE)
    for f in compute.term_files:
        cat = load_term_file(f, cat)
    parse_model(compute.model, cat)


def _check_planning(p: Planning) -> None:
    """The plan's name, target and record budget."""
    if p.plan not in PLANS:
        raise UserError(
            f"--plan {p.plan}: give fixed (the method's plan), adaptive, poses or poses16"
        )
    if not (math.isfinite(p.target) and p.target > 0.0):
        raise UserError(f"--target {p.target:g}: give the worst σ/tolerance to reach, e.g. 0.05")
    if not 0 <= p.max_extra <= MAX_EXTRA:
        raise UserError(
            f"--max-extra {p.max_extra}: give 0 to {MAX_EXTRA} records ({MAX_EXTRA} is "
            "about an hour of the operator's time)"
        )


def _check_names(p: Provenance) -> None:
    """Names written into every record's header and the archive: printable, one line."""
    for opt, name in (("--operator", p.operator), ("--bench", p.bench), ("--lot", p.lot)):
        problem = None if name is None else name_problem(name)
        if problem is not None:  # was: written into every record's header and the archive
            raise UserError(f"{opt}: {problem}")


def _checked_serial(f: SessionFiles) -> SessionFiles:
    """The serial number as parsed."""
    if f.serial is None:
        return f
    try:
        return replace(f, serial=parse_serial(f.serial))
    except ValueError as exc:
        raise UserError(f"--serial: {exc}") from None


def _check_redo(f: SessionFiles, yes: bool) -> None:
    """The records --redo names are record names; --yes has the serial number."""
    unknown = [n for n in f.redo if not RECORD_NAME_RE.fullmatch(n)]
    if unknown:
        names = (*STATIC_NAMES, *TURN_NAMES, CLOSING_NAME)
        raise UserError(
            f"--redo {unknown[0]}: not a record name; use one of " + ", ".join(names)
            + " or a repeat of one (x_ccw_2)"
        )  # fmt: skip
    if yes and f.serial is None:
        raise UserError("--yes needs --serial (the serial number is mandatory)")


def _checked_boards(o: DialogueOptions, f: SessionFiles) -> tuple[tuple[str, str], ...]:
    """The other boards of a sitting of several: serials parsed, none twice, and what a
    sitting of several does not do yet refused."""
    if not o.more_boards:
        return ()
    if f.serial is None:
        raise UserError("several --port need one --serial each, in the same order")
    boards = []
    for port, serial in o.more_boards:
        try:
            boards.append((port, parse_serial(serial)))
        except ValueError as exc:
            raise UserError(f"--serial {serial}: {exc}") from None
    serials = [f.serial, *(s for _, s in boards)]
    twice = next((s for s in serials if serials.count(s) > 1), None)
    if twice is not None:
        raise UserError(f"--serial {twice} is given twice: each board has its own serial number")
    if o.planning.plan != "fixed":
        raise UserError(
            f"--plan {o.planning.plan} takes one --port: a sitting of several boards follows "
            "the method's plan (leave --plan out)"
        )
    if f.capture is not None:
        raise UserError("--capture names one board's capture: leave it out with several --port")
    return tuple(boards)


def _checked_schedule(s: Schedule) -> Schedule:
    """The accumulation time as parsed; turns, warm-up and pause in their ranges."""
    static_seconds = s.static_seconds
    if static_seconds is not None:
        try:
            static_seconds = parse_seconds(str(static_seconds))
        except ValueError as exc:
            raise UserError(f"--static-seconds: {exc}") from None
    if s.turns is not None and not 1 <= s.turns <= MAX_TURNS:
        raise UserError(f"--turns must be 1 to {MAX_TURNS} (3 or fewer recommended)")
    if not math.isfinite(s.warmup_s) or s.warmup_s < 0:
        raise UserError("--warmup must be 0 (skip) or a number of seconds")
    if s.ready_s is not None and (not math.isfinite(s.ready_s) or s.ready_s < 0):
        raise UserError("--ready-seconds must be 0 or more")
    return replace(s, static_seconds=static_seconds)


def _schedule_words(s: Schedule) -> list[str]:
    """The warm-up and the pause before a turn as command-line words."""
    words = ["--warmup", _number(s.warmup_s)]
    if s.ready_s is not None:
        words += ["--ready-seconds", _number(s.ready_s)]
    return words


def _compute_words(c: ComputeSettings) -> list[str]:
    """The options of how the result is computed that differ from the defaults."""
    words: list[str] = []
    given = c.issue.site_from or (FROM_OPTIONS, FROM_OPTIONS)  # the bench file's: it says them
    if c.latitude_deg != DEFAULT_LATITUDE_DEG and given[0] == FROM_OPTIONS:
        words += ["--latitude", _number(c.latitude_deg)]
    if c.height_m != DEFAULT_HEIGHT_M and given[1] == FROM_OPTIONS:
        words += ["--height", _number(c.height_m)]
    if c.issue.bench is not None:
        words += ["--bench-file", c.issue.bench.path]
    if c.issue.customer:
        words += ["--customer", c.issue.customer]
    if c.model != "base":
        words += ["--model", c.model]
    for f in c.term_files:
        words += ["--term-file", f]
    if c.verify:
        words += ["--verify", c.verify]
    if c.decision_rule != DEFAULT_RULE:
        words += ["--decision-rule", c.decision_rule]
    for opt, val in (("--floor", c.floor), ("--thermal", c.thermal), ("--noise", c.noise_file)):
        if val:
            words += [opt, val]
    return words


def _provenance_words(p: Provenance) -> list[str]:
    """Who, which bench, where archived and the lot, as given."""
    words: list[str] = []
    for opt, val in (("--operator", p.operator), ("--bench", p.bench),
                     ("--archive", p.archive), ("--lot", p.lot)):  # fmt: skip
        if val:
            words += [opt, val]
    return words


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
