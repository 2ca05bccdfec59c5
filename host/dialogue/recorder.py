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
from host.dialogue.boards import Unit, UnitsInHand, lost_at, lost_line, show_means
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

#: one measurement of every board in the sitting: (unit, its acquisition) each
Measured = list[tuple[Unit, Acquisition]]

#: --yes: a measurement whose default answer is "repeat" is tried at most this many times
YES_MAX_ATTEMPTS = 3
#: --yes: give up waiting for a vanished board after this many seconds
YES_RECONNECT_S = 60.0


class Recorder(UnitsInHand):
    """The records of a dialogue: ``op`` asks, the boards of its units measure (one
    :class:`host.dialogue.boards.Unit` per ``--port``); each unit's files go to its directory.
    ``board``, ``serial``, ``out_dir``, ``done``, ``accepted`` and ``sitting`` are those of the
    unit in hand (:meth:`_on`; the first unless a step of every unit is taken)."""

    def __init__(
        self,
        opts: DialogueOptions,
        console: Console,
        port_factory: Callable[[str], serial.SerialBase] | None = None,
    ) -> None:
        self.opts = opts
        self.op = Questions(console, yes=opts.yes, idle=self._idle)
        serials = (opts.files.serial, *(s for _, s in opts.more_boards))
        self.units = [Unit(Board(with_serial(port, serials[k]), port_factory,  # a virtual board:
                                 opts.link.stall_s, self._warner(k),  # that unit
                                 opts.link.hello_timeout_s, opts.link.sample_stall_s))
                      for k, port in enumerate(opts.ports)]  # fmt: skip
        #: the unit whose board, serial and records the per-unit steps use
        self.unit = self.units[0]
        self.g = local_gravity(opts.compute.latitude_deg, opts.compute.height_m)
        self.turns: int | None = opts.schedule.turns
        self.static_seconds: float | None = opts.schedule.static_seconds
        self._in_idle = False
        self._session_start_ns = time.monotonic_ns()
        #: True while the warm-up runs (Ctrl+C there discards no measurement)
        self.in_warm_up = False
        #: True while the boards' self-tests run (a board lost then is named so)
        self.in_self_test = False
        #: the record being measured (what a board that leaves the sitting is named at)
        self._measuring = ""

    def _warner(self, k: int) -> Callable[[str], None]:
        """The board warnings of unit ``k``: named by its serial in a sitting of several."""

        def warn(text: str) -> None:
            who = self.units[k].serial if self.several else ""
            self._warn(f"{who}: {text}" if who else text)

        return warn

    # ---- plumbing ------------------------------------------------------------------------
    def _warn(self, text: str) -> None:
        self.op.say(f"!!! {text}")

    def _idle(self) -> None:
        """While waiting for the operator: keep reading the boards; recover one that vanished."""
        if self._in_idle:
            return
        self._in_idle = True
        try:
            for u in self.live:
                if u.board.link is None:
                    continue
                try:
                    u.board.pump()
                except (LinkLost, LinkTimeout) as exc:
                    self._recover_unit(u, exc, measuring=False)
        finally:
            self._in_idle = False

    def _recover(self, exc: Exception, measuring: bool) -> None:
        """The board in hand vanished or went silent: wait for it (no pumping of the dead
        link)."""
        limit = self.opts.link.reconnect_timeout_s
        if limit is None and self.opts.yes:
            limit = YES_RECONNECT_S
        was, self._in_idle = self._in_idle, True
        try:
            reconnect(self.board, self.op, exc, measuring=measuring, yes=self.opts.yes,
                      limit_s=limit, resume_hint=self._resume_hint)  # fmt: skip
        finally:
            self._in_idle = was

    def _recover_unit(self, unit: Unit, exc: Exception, measuring: bool = True) -> None:
        """``unit``'s board vanished: wait for it; in a sitting of several, one that does not
        come back (or that the operator gives up on) leaves the sitting."""
        with self._on(unit):
            if not self.several:
                self._recover(exc, measuring)
                return
            self._warn(f"{unit.serial}: the board on {unit.board.url} is gone")
            try:
                self._recover(exc, measuring)
            except ResumableError as gone:
                self._drop(unit, str(gone).split(";")[0])

    def _drop(self, unit: Unit, why: str) -> None:
        """``unit`` leaves the sitting: named, with the command that resumes it alone; its
        records stay, its directory is released. The last unit to leave ends the sitting."""
        unit.lost = why
        at = lost_at(self._measuring, self.in_self_test)
        words = self.opts.alone(unit.serial, unit.board.url, unit.out_dir).command_words(
            unit.serial, static_seconds=self.static_seconds, turns=self.turns,
            port=unit.board.url)  # fmt: skip
        lost = lost_line(unit.serial, at, why)
        self.op.say(said_with_command("!!! " + lost, words, first=0))
        unit.board.close()
        if unit.sitting is not None:
            unit.sitting.release()
        if not self.live:
            raise ResumableError(f"every board left the sitting {at}")

    def command(self, then: Sequence[str] = ("--resume",)) -> str:
        """This session's command line (every option given or answered) plus ``then``."""
        return shlex.join(self.command_words(then))

    def command_words(self, then: Sequence[str] = ("--resume",)) -> list[str]:
        """The words of :meth:`command` (unquoted)."""
        o, first = self.opts, self.units[0]
        return o.command_words(first.serial, static_seconds=self.static_seconds,
                               turns=self.turns, port=first.board.url, then=then)  # fmt: skip

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
        if self.several:
            where = ", ".join(str(u.out_dir) for u in self.units)
            text = f"{lead}the accepted records are kept in {where}; continue the sitting with:"
            return said_with_command(text, self.command_words(), first=first)
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
        for u in self.live:
            if first in u.done and CLOSING_NAME in u.done:
                on = f"{u.serial}: " if self.several else ""
                op.say(on + screens.closing_difference(u.done[first], u.done[CLOSING_NAME]))

    def _measure_static(
        self, name: str, seconds: float | None = None, stop: StaticStop | None = None,
        planned: str = "",
    ) -> None:  # fmt: skip
        """Measure static record ``name`` on every board for ``seconds`` s (None: the
        accumulation time), or with ``stop`` (one board) until it says the record has enough
        (at most ``seconds``), then Save/repeat; its header then says why it stopped
        (``planned``: why, without ``stop``: a record the adaptive plan's planner asked for)."""
        op = self.op
        axis, side = name.split("_")[:2]  # x_up_2: the attitude x_up again
        assert self.static_seconds is not None
        length = self.static_seconds if seconds is None else seconds
        attempts = 0
        self._measuring = name
        while True:
            attempts += 1
            self._hint("place", name=f"{axis}_{side}")
            op.any_key(screens.place_prompt(axis, side))
            why: list[str] = []

            def enough(counts: np.ndarray, elapsed_s: float, why: list[str] = why) -> bool:
                assert stop is not None
                accel, gyro, _ = self.board.physical(counts)
                why.extend(w for w in [stop(accel, gyro, elapsed_s)] if w)
                return bool(why)

            got = self._acquire_all(name, length, "Measuring", None if stop is None else enough)
            if got is None:
                continue
            recs = self._records(name, got, {"kind": "static", **PLACED})
            if stop is not None:  # one board (--plan adaptive)
                rec = recs[0][1]
                why = why or [stop(rec.accel, rec.gyro, length) or ""]
                rec.meta[STOPPED_KEY] = why[0]
                op.say(f"{name}: stopped, {why[0].split(':')[0]}")
            elif planned:  # one board (--plan adaptive)
                recs[0][1].meta[STOPPED_KEY] = planned
                op.say(f"{name}: stopped, {planned.split(':')[0]}")
            problems = self._static_checks(name, got, recs)
            if self._decide_all(name, problems, attempts):
                self._save_all(recs, problems)
                return

    def _static_checks(
        self, name: str, got: Measured, recs: list[tuple[Unit, Record]]
    ) -> dict[Unit, list[str]]:
        """Each board's static record shown (one board: its table; several: a mean/std line
        each) and checked; the problems of each."""
        if self.several:
            show_means(self.op, [(u.serial, r) for u, r in recs])
        problems: dict[Unit, list[str]] = {}
        for (u, acq), (_, rec) in zip(got, recs, strict=True):
            with self._on(u):
                if not self.several:
                    screens.show_table(self.op, rec)
                problems[u] = self._loss_problems(name, acq)
                problems[u] += static_problems(rec, self.g, u.serial)
        return problems

    def _hint(self, action: str, **kw: object) -> None:
        """Tell every board's virtual operator what the operator is asked (one motion for
        all: the boards share the cube)."""
        for u in self.live:
            u.board.hint(action, **kw)

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
        self._measuring = name
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
            self._hint("turn", axis=axis, direction=direction, turns=n, window_s=window)
            got = self._acquire_all(name, window, "Turn now!")
            if got is None:
                continue
            recs = self._records(
                name, got, {"kind": "turn", "turns": str(n), "direction": direction,
                            "window_s": f"{window:g}", **PLACED},
            )  # fmt: skip
            problems = self._turn_checks(name, got, recs, n)
            lead, rec = recs[0]
            if decide is not None and not problems[lead]:  # one board (--plan adaptive)
                rec.meta[STOPPED_KEY] = decide(rec)
                op.say(f"{axis} turns: {rec.meta[STOPPED_KEY].split(':')[0]}")
            if self._decide_all(name, problems, attempts):
                self._save_all(recs, problems)
                return

    def _turn_checks(
        self, name: str, got: Measured, recs: list[tuple[Unit, Record]], n: int
    ) -> dict[Unit, list[str]]:
        """Each board's turn record shown (several: under its serial) and checked; the
        problems of each."""
        problems: dict[Unit, list[str]] = {}
        for (u, acq), (_, rec) in zip(got, recs, strict=True):
            with self._on(u):
                if self.several:
                    self.op.say(f"{u.serial}:")
                problems[u] = self._loss_problems(name, acq)
                problems[u] += self._check_turn(rec, acq, n)
        return problems

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
        """One acquisition of the board in hand (:meth:`_acquire_all` of a sitting of one);
        None: propose again."""
        got = self._acquire_all(name, seconds, title, enough)
        return None if got is None else got[0][1]

    def _acquire_all(
        self,
        name: str,
        seconds: float,
        title: str,
        enough: Callable[[np.ndarray, float], bool] | None = None,
    ) -> Measured | None:
        """One measurement on every board still in the sitting, from one start beep
        (:func:`host.dialogue.measurement.acquire`); None: propose it again."""
        units = self.live
        who = [u.serial for u in units] if self.several else []
        acqs = acquire([u.board for u in units], self.op, name, seconds, title,
                       yes=self.opts.yes, recover=lambda k, e: self._recover_unit(units[k], e),
                       resume_hint=self._resume_hint, enough=enough, who=who,
                       drop=self._dropper(units))  # fmt: skip
        return None if acqs is None else list(zip(units, acqs, strict=True))

    def _dropper(self, units: list[Unit]) -> Callable[[int, str], None] | None:
        """How board ``k`` of ``units`` leaves the sitting (one board: it cannot; None)."""
        return (lambda k, why: self._drop(units[k], why)) if self.several else None

    def _records(
        self, name: str, got: Measured, extra: dict[str, str]
    ) -> list[tuple[Unit, Record]]:
        """Each board's record of the measurement ``got`` (:meth:`_record`)."""
        out = []
        for u, acq in got:
            with self._on(u):
                out.append((u, self._record(name, acq, extra)))
        return out

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
            on = f"{self.serial}: " if self.several else ""
            self.op.say(on + screens.loss_line(name, acq))
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

    def _decide_all(self, name: str, problems: dict[Unit, list[str]], attempts: int) -> bool:
        """Save (True) or repeat (False) the measurement of every board, asked once; in a
        sitting of several each problem is named by its board, and a board whose record is
        still bad may leave the sitting (``--yes``: after its last attempt) so that the
        others save theirs."""
        if not self.several:
            return self._decide(name, problems[self.units[0]], attempts)
        op = self.op
        bad = {u: p for u, p in problems.items() if p and u.lost is None}
        for u, ps in bad.items():
            for p in ps:
                op.say(f"!!! {u.serial}: {p}")
        for u, ps in bad.items():
            if self.opts.yes and attempts >= YES_MAX_ATTEMPTS:
                self._drop(u, f"{name} still wrong after {attempts} attempts: {ps[0]}")
            elif not self.opts.yes and attempts >= 2 and op.yes_no(
                f"Drop {u.serial} from the sitting (its session stays incomplete) <Y> or "
                "keep it <N>?", False,
            ):  # fmt: skip
                self._drop(u, f"dropped at the operator's word: {ps[0]}")
        if not any(u.lost is None for u in bad):
            return op.yes_no("Save <Y> or repeat <N>?", True)
        return not op.yes_no("Repeat <Y> or save anyway <N>?", True)

    def _save_all(self, recs: list[tuple[Unit, Record]], problems: dict[Unit, list[str]]) -> None:
        """Each board's accepted record saved in its directory (:meth:`_save`), but a
        board's that left the sitting or that has the record already (``--resume``)."""
        for u, rec in recs:
            if u.lost is None and rec.name not in u.done:
                with self._on(u):
                    self._save(rec, problems[u])

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
