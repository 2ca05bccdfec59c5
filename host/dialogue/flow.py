"""The live calibration dialogue (method.md §5): its sequence with the operator on a board.

``python -m host calibrate --port PORT ...`` calls :func:`run_dialogue`. The dialogue only asks,
decides and records, in this order: the board's identity, the serial number, the self-test, the
warm-up, the six faces (stage 1), the turns (stage 2), the closing check, the results. One
measurement — its acquisition through :class:`host.board.driver.Board`, the record and its header,
its checks — is :mod:`host.dialogue.measurement`; what is shown is :mod:`host.dialogue.screens`; the
options are :mod:`host.dialogue.options`. A measurement the operator accepts becomes a
:class:`host.session.records.Record`, written atomically as ``SERIAL_name.txt``; at the end
:func:`host.calib.publish.compute_and_write` computes and writes the results, exactly as ``calibrate
--from-dir`` does.

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
measured again; the results are computed from all of this serial's records in the directory.
``--redo NAME`` keeps the others and measures NAME again. Nothing accepted is replaced, and one
process at a time writes a directory (:mod:`host.dialogue.sitting`). SIGTERM and SIGHUP end a
session as Ctrl+C does.

Operator hints: a port with ``operator_hint`` (the ``sim://`` virtual board) is told what the
human is asked (``place`` before the placement prompt, ``turn`` at the start beep of a turn).
"""

from __future__ import annotations

import argparse
import contextlib
import shlex
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import serial

from host.board.acquisition import Acquisition, BoardReset, MeasurementAborted, SensorFault
from host.board.driver import Board, BoardInfo, default_port
from host.board.link import LinkLost, LinkTimeout
from host.calib.calibration import stage1
from host.calib.publish import ComputeSettings, compute_and_write, show_result
from host.calib.report import verdict_line
from host.dialogue import adaptive, screens
from host.dialogue.console import (
    Console,
    EndedBySignal,
    Questions,
    TerminalConsole,
    signals_end_like_ctrl_c,
)
from host.dialogue.measurement import (
    PLACED,
    acquire,
    capture_path,
    loss_problems,
    make_record,
    over_range,
    reconnect,
    self_test,
    static_problems,
    turn_problems,
)
from host.dialogue.options import (
    CLOSING_NAME,
    DEFAULT_READY_S,
    DEFAULT_TURNS,
    MAX_RECOMMENDED_TURNS,
    DialogueOptions,
    check_out_dir,
    parse_seconds,
    parse_serial,
    parse_turns,
)
from host.dialogue.sitting import SittingDirectory
from host.errors import RecordCheckError, ResumableError, UserError, write_error
from host.session.checks import failed_record
from host.session.directory import DirectoryBusy, read_session, record_path, write_record
from host.session.method import local_gravity, record_stats
from host.session.records import STATIC_NAMES, TURN_NAMES, WARMUP_NAME, Record, turn_window_s
from host.wire import sensor

#: --yes: a measurement whose default answer is "repeat" is tried at most this many times
YES_MAX_ATTEMPTS = 3
#: --yes: give up waiting for a vanished board after this many seconds
YES_RECONNECT_S = 60.0


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
        self.board = Board(opts.port or "sim://", port_factory, opts.stall_s, self._warn,
                           opts.hello_timeout_s, opts.sample_stall_s)  # fmt: skip
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
        limit = self.opts.reconnect_timeout_s
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
        return self.opts.command(self.serial, static_seconds=self.static_seconds,
                                 turns=self.turns, port=self.board.url, then=then)  # fmt: skip

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
        screens.show_opening(op, self.board.url)
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
        self.sitting = SittingDirectory(self.out_dir, self.serial, self.command(then=()))
        self._take_stock()
        self._start_capture()
        self._self_test()
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
        if opts.plan == "adaptive" and all(n in self.done for n in STATIC_NAMES + TURN_NAMES):
            adaptive.measure_until_enough(self, opts)
        if opts.closing and CLOSING_NAME not in self.done and STATIC_NAMES[0] in self.done:
            self._closing_check()
        return self._results()

    def _connect(self) -> BoardInfo:
        try:
            return self.board.connect()
        except LinkTimeout as exc:
            raise UserError(str(exc)) from None

    def _start_capture(self) -> None:
        path = self.opts.capture or capture_path(self.out_dir, self.serial)
        self.board.capture.start(path)
        self.op.say(f"Recording the link to {path}")

    def _take_stock(self) -> None:
        """Records of this serial already in the output directory: kept (--resume, --redo),
        or moved aside with the rest of their sitting."""
        assert self.sitting is not None
        if not self.opts.keeps_records:
            moved = self.sitting.set_aside_earlier()
            if moved:
                self._warn(moved)
            return
        names = [n for n in self._existing_names() if n not in self.opts.redo]
        self.done.update(self.sitting.read_kept(names, self._warn))
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
            static = [r.duration_s for n, r in self.done.items() if n in STATIC_NAMES]
            if self.static_seconds is None and static:  # asked once, when they were measured
                self.static_seconds = screens.kept_accumulation(self.op, static)

    def _self_test(self) -> None:
        """The MPU-6000's self-test, into every record's header (measurement.self_test)."""
        self_test(self.board, self.op, YES_MAX_ATTEMPTS, lambda e: self._recover(e, False))

    def _warm_up(self) -> None:
        """The warm-up (method.md §5 step 3), recorded as ``SERIAL_warmup.txt``: one attitude,
        the chip temperature rising — the thermal calibration's first ramp
        (``python -m host thermal``). Any key skips the rest of the wait (nothing recorded)."""
        s = self.opts.warmup_s
        if s <= 0 or (self.opts.keeps_records and self.done and screens.no_warm_up(self.op)):
            return
        op = self.op
        op.say(screens.warm_up_line(s, self.opts.yes))
        tick = screens.warm_up_progress(op, s)
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
            path = self._keep_earlier(WARMUP_NAME)
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
        op.say(screens.closing_line(first))
        if self.static_seconds is None:
            self.static_seconds = float(self.done[first].duration_s)
        self._measure_static(CLOSING_NAME)
        op.say(screens.closing_difference(self.done[first], self.done[CLOSING_NAME]))

    def _measure_static(self, name: str) -> None:
        op = self.op
        axis, side = name.split("_")[:2]  # x_up_2: the attitude x_up again
        assert self.static_seconds is not None
        attempts = 0
        while True:
            attempts += 1
            self.board.hint("place", name=f"{axis}_{side}")
            op.any_key(screens.place_prompt(axis, side))
            acq = self._acquire(name, self.static_seconds, "Measuring")
            if acq is None:
                continue
            rec = self._record(name, acq, {"kind": "static", **PLACED})
            screens.show_table(op, rec)
            problems = self._loss_problems(name, acq)
            problems += static_problems(rec, self.g, self.serial)
            if self._decide(name, problems, attempts):
                self._save(rec, problems)
                return

    def _show_stage1(self) -> None:
        stats = {n: record_stats(self.done[n]) for n in STATIC_NAMES}
        screens.show_stage1(self.op, stage1(stats, self.g), self.g)

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
        op.say(screens.turn_window_line(window))
        for name in names:
            self._measure_turn(name, n, window)

    def _measure_turn(self, name: str, n: int, window: float) -> None:
        op = self.op
        axis, direction = name.split("_")[:2]  # x_ccw_2: the turn x_ccw again
        attempts = 0
        while True:
            attempts += 1
            op.any_key(screens.turn_place_prompt(axis))
            op.say(screens.get_ready_line(n, direction, window))
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
                            "window_s": f"{window:g}", **PLACED},
            )  # fmt: skip
            problems = self._loss_problems(name, acq)
            problems += self._check_turn(rec, acq, n)
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
            rec, self.g, self.serial, statics, self.out_dir, n, self.opts.latitude_deg
        )
        return problems

    # ---- one measurement -----------------------------------------------------------------
    def _acquire(self, name: str, seconds: float, title: str) -> Acquisition | None:
        """One acquisition (:func:`host.dialogue.measurement.acquire`); None: propose again."""
        return acquire(self.board, self.op, name, seconds, title, yes=self.opts.yes,
                       recover=lambda exc: self._recover(exc, measuring=True),
                       resume_hint=self._resume_hint)  # fmt: skip

    def _record(self, name: str, acq: Acquisition, extra: dict[str, str]) -> Record:
        who = {"operator": self.opts.operator, "bench": self.opts.bench}  # the report's
        extra = {**extra, **{k: " ".join(v.split()) for k, v in who.items() if v and v.strip()}}
        return make_record(self.board, self.serial, name, acq, extra, self._session_start_ns)

    def _loss_problems(self, name: str, acq: Acquisition) -> list[str]:
        if acq.lost:
            self.op.say(screens.loss_line(name, acq))
        return loss_problems(name, acq, self.opts.loss_limit)

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
            pdf=self.opts.pdf,
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
        pdf = f", {pub.pdf_path}" if pub.pdf_path is not None else ""
        op.say(f"Results: {pub.report_path} and {pub.json_path}{pdf}")
        show_result(pub.result, self.opts.json)
        if self.opts.after_publish is not None:  # calibrate archives the result
            op.say(self.opts.after_publish(self.out_dir, session))
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
    :class:`host.dialogue.console.ScriptedConsole`). ``port_factory(url)``: opens the port
    (default :func:`host.board.link.open_port`). Returns the exit status: 0 every value within
    tolerance, 1 some outside, 130 aborted with Ctrl+C. UserError for what the user can fix.
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
        with signals_end_like_ctrl_c():
            if note:
                con.say(note)
            session = CalibrationDialogue(opts, con, port_factory)
            outcome = session.run()
            return 0 if outcome.result is not None and outcome.result.all_passed else 1
    except KeyboardInterrupt as exc:
        why = exc.name if isinstance(exc, EndedBySignal) else "Ctrl+C"
        with contextlib.suppress(OSError):  # after SIGHUP the terminal may be gone
            con.end_progress()
            con.say("")
            con.say(
                f"Aborted ({why}) during the warm-up (not recorded)."
                if session is not None and session.in_warm_up
                else f"Aborted ({why}): the measurement in progress is discarded."
            )
            if session is not None and session.serial:
                con.say(session._resume_hint())
        return exc.exit_status if isinstance(exc, EndedBySignal) else 130
    except (UserError, OSError) as exc:
        # a session ending on an error (disk full, sensor failed, board gone) always says how
        # to continue with the records already accepted
        told = isinstance(exc, (ResumableError, DirectoryBusy))  # it says what to do
        if session is None or not session.serial or told:
            raise
        text = str(exc) if isinstance(exc, UserError) else str(write_error(exc.filename, exc))
        raise UserError(f"{text}; {session._resume_hint()}") from None
    finally:
        if session is not None:
            session.board.close()
            if session.sitting is not None:
                session.sitting.release()
        if term is not None:
            term.close()
