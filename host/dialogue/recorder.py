"""The records of the dialogue (method.md §5): the faces, the closing check and the turns, each
measured until the operator saves it — prompt, acquisition, checks, Save/repeat, the file.

:class:`Recorder` holds what every measurement needs (the board, the operator's questions, the
records accepted so far) and how a vanished board is waited for; the sequence of the sitting
around it (identity, self-test, warm-up, results) is :class:`host.dialogue.flow.
CalibrationDialogue`. One acquisition and its checks are :mod:`host.dialogue.measurement`.
"""

from __future__ import annotations

import shlex
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import serial

from host.bench.options import with_serial
from host.board.acquisition import Acquisition
from host.board.driver import Board
from host.board.link import LinkLost, LinkTimeout
from host.calib.calibration import stage1
from host.calib.commands import ERROR_LEAD, said_with_command
from host.dialogue import screens
from host.dialogue.console import Console, Questions
from host.dialogue.measurement import (
    PLACED,
    acquire,
    loss_problems,
    make_record,
    over_range,
    reconnect,
    static_problems,
    turn_problems,
)
from host.dialogue.options import (
    CLOSING_NAME,
    DEFAULT_READY_S,
    DEFAULT_TURNS,
    MAX_RECOMMENDED_TURNS,
    DialogueOptions,
    parse_seconds,
    parse_turns,
)
from host.dialogue.sitting import SittingDirectory
from host.errors import ResumableError
from host.session.directory import record_names, write_record
from host.session.method import local_gravity, record_stats
from host.session.records import (
    RECORD_NAME_RE,
    STATIC_NAMES,
    STOPPED_KEY,
    TARGET_KEY,
    Record,
    turn_window_s,
)

#: when a static record has enough: stop(accel (N, 3) m/s², gyro (N, 3) °/s, elapsed s) -> why
#: it stops now (its header's ``stopped``), or None: go on
StaticStop = Callable[[np.ndarray, np.ndarray, float], str | None]

#: --yes: a measurement whose default answer is "repeat" is tried at most this many times
YES_MAX_ATTEMPTS = 3
#: --yes: give up waiting for a vanished board after this many seconds
YES_RECONNECT_S = 60.0


class Recorder:
    """The records of a dialogue: ``op`` asks, ``board`` measures; files go to its directory."""

    def __init__(
        self,
        opts: DialogueOptions,
        console: Console,
        port_factory: Callable[[str], serial.SerialBase] | None = None,
    ) -> None:
        self.opts = opts
        self.op = Questions(console, yes=opts.yes, idle=self._idle)
        url = with_serial(opts.port or "sim://", opts.files.serial)  # a virtual board: that unit
        self.board = Board(url, port_factory, opts.link.stall_s, self._warn,
                           opts.link.hello_timeout_s, opts.link.sample_stall_s)  # fmt: skip
        self.g = local_gravity(opts.compute.latitude_deg, opts.compute.height_m)
        self.serial = ""
        self.out_dir = Path()
        self.done: dict[str, Record] = {}
        self.accepted: list[str] = []
        self.turns: int | None = opts.schedule.turns
        self.static_seconds: float | None = opts.schedule.static_seconds
        self._in_idle = False
        self._session_start_ns = time.monotonic_ns()
        #: True while the warm-up runs (Ctrl+C there discards no measurement)
        self.in_warm_up = False
        self.sitting: SittingDirectory | None = None  # the output directory, locked

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
        """The board vanished or went silent: wait for it (no pumping of the dead link)."""
        limit = self.opts.link.reconnect_timeout_s
        if limit is None and self.opts.yes:
            limit = YES_RECONNECT_S
        self._in_idle = True
        try:
            reconnect(self.board, self.op, exc, measuring=measuring, yes=self.opts.yes,
                      limit_s=limit, resume_hint=self._resume_hint)  # fmt: skip
        finally:
            self._in_idle = False

    def command(self, then: Sequence[str] = ("--resume",)) -> str:
        """This session's command line (every option given or answered) plus ``then``."""
        return shlex.join(self.command_words(then))

    def command_words(self, then: Sequence[str] = ("--resume",)) -> list[str]:
        """The words of :meth:`command` (unquoted)."""
        o = self.opts
        return o.command_words(self.serial, static_seconds=self.static_seconds,
                               turns=self.turns, port=self.board.url, then=then)  # fmt: skip

    def _resume_hint(self, before: str = "", first: int = ERROR_LEAD) -> str:
        """``before`` (what stopped the session), what is kept and the command that continues
        it, on lines of its own (:func:`host.calib.commands.said_with_command`: within 80
        columns but for a long path, and it runs as printed); ``first``: the columns before
        the first line (an error's ``error: ``)."""
        lead = f"{before}; " if before else ""
        if not self.serial:
            cmd = ["python3", "-m", "host", "calibrate", "--port", self.board.url]
            return said_with_command(f"{lead}nothing was saved; start again with:", cmd,
                                     first=first)  # fmt: skip
        n = len(self._existing_names())
        text = f"{lead}{n} accepted records are kept in {self.out_dir}; continue with:"
        return said_with_command(text, self.command_words(), first=first)

    def _existing_names(self) -> list[str]:
        """Every record of this serial in the output directory (the repeats too)."""
        return record_names(self.out_dir, self.serial)

    # ---- stage 1 -------------------------------------------------------------------------
    def _ask_static_seconds(self) -> float:
        """The accumulation time per orientation (``--static-seconds``, else asked), s."""
        if self.static_seconds is None:
            self.static_seconds = self.op.ask(
                "Accumulation time per orientation, seconds (typically 10 to a few hundred)",
                parse_seconds,
                option="--static-seconds",
            )
        if self.static_seconds < 10:
            self._warn(f"{self.static_seconds:g} s per orientation is short: noise averages less")
        return self.static_seconds

    def _stage1(self, names: list[str]) -> None:
        self._ask_static_seconds()
        for name in names:
            self._measure_static(name)

    def _closing_check(self, stop: StaticStop | None = None) -> None:
        """The first attitude measured again (:data:`CLOSING_NAME`): the fit takes it as one
        more static record; its difference from the opening measurement is the drift over the
        session, shown here in the channels' units. ``stop``: it ends when it has enough
        (``--plan adaptive``), at most the accumulation time."""
        first = STATIC_NAMES[0]
        op = self.op
        op.say(screens.closing_line(first))
        if self.static_seconds is None:
            self.static_seconds = float(self.done[first].duration_s)
        self._measure_static(CLOSING_NAME, stop=stop)
        op.say(screens.closing_difference(self.done[first], self.done[CLOSING_NAME]))

    def _measure_static(
        self, name: str, seconds: float | None = None, stop: StaticStop | None = None
    ) -> None:
        """Measure static record ``name`` for ``seconds`` s (None: the accumulation time),
        or with ``stop`` until it says the record has enough (at most ``seconds``), then
        Save/repeat; its header then says why it stopped."""
        op = self.op
        axis, side = name.split("_")[:2]  # x_up_2: the attitude x_up again
        assert self.static_seconds is not None
        length = self.static_seconds if seconds is None else seconds
        attempts = 0
        while True:
            attempts += 1
            self.board.hint("place", name=f"{axis}_{side}")
            op.any_key(screens.place_prompt(axis, side))
            why: list[str] = []

            def enough(counts: np.ndarray, elapsed_s: float, why: list[str] = why) -> bool:
                assert stop is not None
                accel, gyro, _ = self.board.physical(counts)
                why.extend(w for w in [stop(accel, gyro, elapsed_s)] if w)
                return bool(why)

            acq = self._acquire(name, length, "Measuring", None if stop is None else enough)
            if acq is None:
                continue
            rec = self._record(name, acq, {"kind": "static", **PLACED})
            if stop is not None:
                why = why or [stop(rec.accel, rec.gyro, length) or ""]
                rec.meta[STOPPED_KEY] = why[0]
                op.say(f"{name}: stopped, {why[0].split(':')[0]}")
            screens.show_table(op, rec)
            problems = self._loss_problems(name, acq)
            problems += static_problems(rec, self.g, self.serial)
            if self._decide(name, problems, attempts):
                self._save(rec, problems)
                return

    def _show_stage1(self) -> None:
        stats = {n: record_stats(self.done[n]) for n in STATIC_NAMES}
        screens.show_stage1(self.op, stage1(stats, self.g), self.g)

    def _measure_again(self, names: Sequence[str]) -> None:
        """``--redo`` records the plan would not ask for by these names (a repeat such as
        ``x_ccw_2``, the planner's ``x_up_3``): each measured again as what its name says, a
        static for the accumulation time, a turn of the session's turns."""
        for name in names:
            if RECORD_NAME_RE.match(name)["dir"] in ("up", "dn"):  # type: ignore[index]
                self._ask_static_seconds()
                self._measure_static(name)
            else:
                n, window = self._ask_turns()
                self._measure_turn(name, n, window)

    # ---- stage 2 -------------------------------------------------------------------------
    def _ask_turns(self) -> tuple[int, float]:
        """The turns per turn record (``--turns``, else asked) and their window, s."""
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
        op.say(screens.turn_window_line(window))
        return n, window

    def _stage2(self, names: list[str]) -> None:
        n, window = self._ask_turns()
        for name in names:
            self._measure_turn(name, n, window)

    def _measure_turn(
        self, name: str, n: int, window: float, decide: Callable[[Record], str] | None = None
    ) -> None:
        """Measure turn record ``name`` (``n`` turns in ``window`` s), then Save/repeat.
        ``decide(record)``: a turn that ends a pair says, in its header, whether another pair
        follows and why (``--plan adaptive``)."""
        op = self.op
        axis, direction = name.split("_")[:2]  # x_ccw_2: the turn x_ccw again
        attempts = 0
        while True:
            attempts += 1
            op.any_key(screens.turn_place_prompt(axis))
            op.say(screens.get_ready_line(n, direction, window))
            ready = self.opts.schedule.ready_s
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
                            "window_s": f"{window:g}", **PLACED},
            )  # fmt: skip
            problems = self._loss_problems(name, acq)
            problems += self._check_turn(rec, acq, n)
            if decide is not None and not problems:
                rec.meta[STOPPED_KEY] = decide(rec)
                op.say(f"{axis} turns: {rec.meta[STOPPED_KEY].split(':')[0]}")
            if self._decide(name, problems, attempts):
                self._save(rec, problems)
                return

    def _check_turn(self, rec: Record, acq: Acquisition, n: int) -> list[str]:
        """Show the six integrals and the range check; return the problems found."""
        info = self.board.info
        assert info is not None
        op = self.op
        problems: list[str] = []
        screens.show_integrals(op, rec)
        over, peak = over_range(acq, rec, info.gyro_alarm_counts)
        if over:
            op.beep()
            op.beep()
            # shown once, with the question (_decide)
            problems.append(screens.range_alarm(over, peak, info.gyro_range_dps))
        else:
            op.say(screens.peak_rate_line(peak, info.gyro_range_dps))
        # the engine's angle check needs the statics' bias, and a turn within the range
        statics = {k: v for k, v in self.done.items() if k in STATIC_NAMES} if not over else {}
        problems += turn_problems(
            rec, self.g, self.serial, statics, self.out_dir, n, self.opts.compute.latitude_deg
        )
        return problems

    # ---- one measurement -----------------------------------------------------------------
    def _acquire(
        self,
        name: str,
        seconds: float,
        title: str,
        enough: Callable[[np.ndarray, float], bool] | None = None,
    ) -> Acquisition | None:
        """One acquisition (:func:`host.dialogue.measurement.acquire`); None: propose again."""
        return acquire(self.board, self.op, name, seconds, title, yes=self.opts.yes,
                       recover=lambda exc: self._recover(exc, measuring=True),
                       resume_hint=self._resume_hint, enough=enough)  # fmt: skip

    def _record(self, name: str, acq: Acquisition, extra: dict[str, str]) -> Record:
        who = {
            "operator": self.opts.provenance.operator,
            "bench": self.opts.provenance.bench,
        }  # the report's
        extra = {**extra, **{k: " ".join(v.split()) for k, v in who.items() if v and v.strip()}}
        if self.opts.planning.plan == "adaptive":  # the report says whether it was met
            extra[TARGET_KEY] = f"{self.opts.planning.target:g}"
        return make_record(self.board, self.serial, name, acq, extra, self._session_start_ns)

    def _loss_problems(self, name: str, acq: Acquisition) -> list[str]:
        if acq.lost:
            self.op.say(screens.loss_line(name, acq))
        return loss_problems(name, acq, self.opts.link.loss_limit)

    def _decide(self, name: str, problems: list[str], attempts: int) -> bool:
        """Save (True) or repeat (False). With problems the default is to repeat."""
        op = self.op
        if not problems:
            return op.yes_no("Save <Y> or repeat <N>?", True)
        for p in problems:
            op.say(f"!!! {p}")
        if self.opts.yes and attempts >= YES_MAX_ATTEMPTS:
            raise ResumableError(
                self._resume_hint(f"{name}: still wrong after {attempts} attempts ({problems[0]})")
            )
        return not op.yes_no("Repeat <Y> or save anyway <N>?", True)

    def _save(self, rec: Record, problems: Sequence[str] = ()) -> None:
        """Write the accepted record; one kept despite ``problems`` carries them in its
        header (``warning``), and the report lists it with them."""
        if problems:
            rec.meta["warning"] = " ".join("; ".join(problems).split())
        path = self._keep_earlier(rec.name)
        write_record(path, rec)
        self.done[rec.name] = rec
        self.accepted.append(rec.name)
        self.op.say(f"Saved {path}")

    def _keep_earlier(self, name: str) -> Path:
        """The path of record ``name``; an earlier record there is moved aside first."""
        assert self.sitting is not None
        path, moved = self.sitting.keep_earlier(name)
        if moved:
            self.op.say(moved[0].upper() + moved[1:])
        return path
