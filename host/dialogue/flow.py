"""The live calibration dialogue (method.md §5): its sequence with the operator on a board.

``python3 -m host calibrate --port PORT ...`` calls :func:`run_dialogue`. The dialogue only asks,
decides and records, in this order: the board's identity, the serial number, the self-test, the
warm-up, the six faces (stage 1), the turns (stage 2), the closing check, the results. The faces,
the turns and the closing check, each until it is saved, are :mod:`host.dialogue.recorder`; one
measurement — its acquisition through :class:`host.board.driver.Board`, the record and its
header, its checks — is :mod:`host.dialogue.measurement`; what is shown is
:mod:`host.dialogue.screens`; the options are :mod:`host.dialogue.options`. A measurement the
operator accepts becomes a :class:`host.session.records.Record`, written atomically as
``SERIAL_name.txt``; at the end :func:`host.calib.publish.compute_and_write` computes and writes
the results, exactly as ``calibrate --from-dir`` does.

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
  :data:`host.dialogue.recorder.YES_RECONNECT_S`) and the same measurement (or the self-test)
  is proposed again. In a sitting of several boards, in every step from the self-test on, only
  the board that vanished is waited for; one that does not come back leaves the sitting, named
  with where it was lost (:func:`host.dialogue.boards.lost_line`), and the others go on.

``--resume``: records already in the output directory (and readable, same serial) are not
measured again — every one, the repeats (``x_ccw_2``, the adaptive planner's) too, kept in the
order they were measured (:func:`host.session.directory.measured_order`), so that
``--plan adaptive`` goes on from them; the results are computed from all of this serial's
records in the directory.
``--redo NAME`` keeps the others and measures NAME again. Nothing accepted is replaced, and one
process at a time writes a directory (:mod:`host.dialogue.sitting`). SIGTERM and SIGHUP end a
session as Ctrl+C does.

Operator hints: a port with ``operator_hint`` (the ``sim://`` virtual board) is told what the
human is asked (``place`` before the placement prompt, ``turn`` at the start beep of a turn).
"""

from __future__ import annotations

import contextlib
import textwrap
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import serial

from host.board.acquisition import (
    Acquisition,
    BoardFailed,
    BoardReset,
    MeasurementAborted,
    SensorFault,
)
from host.board.driver import BoardInfo, acquire_boards, default_port
from host.board.link import LinkLost, LinkTimeout
from host.calib.commands import said_with_command
from host.calib.publish import compute_and_write, show_result
from host.calib.report import verdict_line
from host.calib.values import target_line
from host.dialogue import adaptive, poses, screens
from host.dialogue.boards import Unit
from host.dialogue.console import (
    Console,
    EndedBySignal,
    TerminalConsole,
    signals_end_like_ctrl_c,
)
from host.dialogue.measurement import (
    capture_path,
    self_test,
)
from host.dialogue.options import (
    CLOSING_NAME,
    DialogueOptions,
    check_out_dir,
)
from host.dialogue.recorder import YES_MAX_ATTEMPTS, Recorder
from host.dialogue.sitting import SittingDirectory
from host.errors import RecordCheckError, ResumableError, UserError, write_error
from host.session.checks import failed_record
from host.session.directory import (
    DirectoryBusy,
    Session,
    read_session,
    record_path,
    write_record,
)
from host.session.inputs import parse_serial
from host.session.records import STATIC_NAMES, TURN_NAMES, WARMUP_NAME
from host.wire import sensor

# --------------------------------------------------------------------------- the dialogue

#: called with (output directory, session) once the result files are written; returns the
#: line to say (``calibrate`` archives the result there: host.cli.calibrate.archive_line)
AfterPublish = Callable[[Path, Session], str]


@dataclass
class DialogueResult:
    """What a finished dialogue produced (the records accepted in this sitting, the result)."""

    out_dir: Path
    records: list[str] = field(default_factory=list)  # accepted in this session
    result: Any = None  # host.calib.result.CalibrationResult
    files: tuple[Path, ...] = ()
    #: a sitting of several boards: the other boards' results, and the serials of those
    #: that left the sitting (their sessions incomplete)
    others: list[DialogueResult] = field(default_factory=list)
    lost: list[str] = field(default_factory=list)

    @property
    def all_passed(self) -> bool:
        """Every board of the sitting in it to the end, and every value of each within
        tolerance."""
        mine = self.result is not None and self.result.all_passed
        return mine and not self.lost and all(o.all_passed for o in self.others)


class CalibrationDialogue(Recorder):
    """The §5 dialogue: the sitting's sequence around its records (:class:`host.dialogue.
    recorder.Recorder`)."""

    def __init__(
        self,
        opts: DialogueOptions,
        console: Console,
        port_factory: Callable[[str], serial.SerialBase] | None = None,
        after_publish: AfterPublish | None = None,
    ) -> None:
        super().__init__(opts, console, port_factory)
        #: called once the result files are written (calibrate archives the result there)
        self.after_publish = after_publish

    # ---- the program ---------------------------------------------------------------------
    def run(self) -> DialogueResult:
        for u in self.units:  # each board's identity, serial, directory and capture
            with self._on(u):
                self._join()
        self._self_tests()
        self._warm_up()
        if self.opts.planning.plan in ("poses", "poses16"):  # no cube: poses and moves
            poses.measure_poses(self, self.opts)
        elif self.opts.planning.plan == "adaptive":  # the engine's order and stopping rule
            self._adaptive_records()
        else:
            self._fixed_records()
        return self._each_result()

    def _each_result(self) -> DialogueResult:
        """The results of each board still in the sitting (:meth:`_results`; several: each
        under its serial, one that cannot be computed named and the others computed)."""
        if not self.several:
            return self._results()
        outcomes: list[DialogueResult] = []
        for u in self.live:
            with self._on(u):
                self.op.say(f"Results of {u.serial}:")
                try:
                    outcomes.append(self._results())
                except UserError as exc:
                    self._warn(f"{u.serial}: {exc}")
                    outcomes.append(DialogueResult(u.out_dir))
        lost = [u.serial for u in self.units if u.lost is not None]
        if lost:
            self._warn(f"left the sitting, their sessions incomplete: {', '.join(lost)}")
        head = outcomes[0] if outcomes else DialogueResult(self.units[0].out_dir)
        return replace(head, others=outcomes[1:], lost=lost)

    def _join(self) -> None:
        """The board in hand joins the sitting (:meth:`_open_sitting`, its capture started);
        in a sitting of several, one that cannot be opened or does not answer leaves it,
        named, and the others go on."""
        try:
            self._open_sitting()
            self._start_capture()
        except UserError as exc:
            if not self.several:
                raise
            self._drop(self.unit, str(exc).split(";")[0])

    def _open_sitting(self) -> None:
        """The board's identity, the serial number, the output directory locked and what of
        it is kept."""
        op, opts = self.op, self.opts
        if self.several:  # known before the board speaks: its warnings and leaving name it
            self.serial = self._given_serial() or ""
            self.out_dir = opts.out_dir_for(self.serial)
        if self.unit is self.units[0]:
            screens.show_opening(op, self.board.url)
        info = self._connect()
        on = f"{self.serial}: " if self.several else ""
        op.say(f"{on}Board: {info.describe()}")
        if info.who_am_i != sensor.WHO_AM_I_MPU6000:
            self._warn(f"WHO_AM_I {info.who_am_i:#04x} is not an MPU-6000's 0x68")
        if opts.yes and not self.board.has_operator:
            self._warn("--yes on a real board: nobody is asked to place or turn the cube")
        self.serial = self._given_serial() or op.ask(
            "Serial number (1-12 characters: letters, digits, _ or -)", parse_serial
        )
        self.out_dir = opts.out_dir_for(self.serial)
        check_out_dir(self.out_dir)
        self.sitting = SittingDirectory(self.out_dir, self.serial, self.command(then=()))
        self._take_stock()

    def _given_serial(self) -> str | None:
        """The serial given for the board in hand (``--serial``, one per ``--port``)."""
        k = self.units.index(self.unit)
        return self.opts.files.serial if k == 0 else self.opts.more_boards[k - 1][1]

    def _adaptive_records(self) -> None:
        """--plan adaptive: the engine's records, then the closing check as it says."""
        # --redo: measured again by name first (the engine names new records anew)
        self._measure_again([n for n in self.opts.files.redo if n != CLOSING_NAME])
        plan = adaptive.measure_adaptive(self, self.opts)
        if self._closing_due():

            def stop(a: np.ndarray, g: np.ndarray, t: float) -> str | None:
                return plan.static_stop(CLOSING_NAME, self.done, a, g, t)

            self._closing_check(stop)

    def _fixed_records(self) -> None:
        """The method's records: the six faces, the turns, the repeats --redo names, the
        closing check; each stage asked for (a stage measured already is said so)."""
        op, opts = self.op, self.opts
        need_static = self._lacking(STATIC_NAMES)
        need_turn = self._lacking(TURN_NAMES)
        do_static = bool(need_static)
        if need_static:
            do_static = op.yes_no(
                "Measure the 6 static orientations <Y> or go to the integral gyro calibration <N>?",
                True,
            )
        elif opts.keeps_records:
            op.say(f"The six static orientations are already measured ({self._kept_by()}).")
        if do_static:
            self._stage1(need_static)
        do_turns = bool(need_turn)
        if not self._lacking(STATIC_NAMES):
            self._each_stage1()
            if need_turn and do_static:
                do_turns = op.yes_no("Integral gyro calibration <Y> or results <N>?", True)
        if not need_turn and opts.keeps_records:
            op.say(f"The six turns are already measured ({self._kept_by()}).")
        if do_turns and need_turn:
            self._stage2(need_turn)
        base = (*STATIC_NAMES, *TURN_NAMES, CLOSING_NAME)
        self._measure_again([n for n in opts.files.redo if n not in base])  # x_ccw_2, x_up_3 …
        if self._closing_due():
            self._closing_check()

    def _lacking(self, names: Sequence[str]) -> list[str]:
        """Those of ``names`` that a board still in the sitting lacks (each is measured on
        every board at once, and saved by those that lack it)."""
        return [n for n in names if any(n not in u.done for u in self.live)]

    def _each_stage1(self) -> None:
        """Stage 1's summary of each board (several: under its serial)."""
        for u in self.live:
            with self._on(u):
                if self.several:
                    self.op.say(f"{u.serial}:")
                self._show_stage1()

    def _kept_by(self) -> str:
        """Which option kept the records measured already: ``--redo NAME`` (it measures only
        those it names again) or ``--resume``."""
        redo = self.opts.files.redo
        return f"kept: --redo measures {', '.join(redo)} only" if redo else "--resume"

    def _closing_due(self) -> bool:
        """The closing check is to be measured: asked for, not measured yet, and the first
        attitude it repeats measured."""
        return self.opts.schedule.closing and any(
            CLOSING_NAME not in u.done and STATIC_NAMES[0] in u.done for u in self.live
        )

    def _connect(self) -> BoardInfo:
        try:
            return self.board.connect()
        except LinkTimeout as exc:
            raise UserError(str(exc)) from None

    def _start_capture(self) -> None:
        path = self.opts.files.capture or capture_path(self.out_dir, self.serial)
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
        self.done.update(self.sitting.read_kept(self.opts.files.redo, self._warn))
        if self.opts.files.redo and self.unit is self.units[0]:
            self.op.say(f"Measuring again: {', '.join(self.opts.files.redo)} (--redo)")
        if self.opts.keeps_records:
            on = f"{self.serial}: " if self.several else ""
            kept = f"{on}Resuming: kept {', '.join(self.done) or 'nothing'}"
            self.op.say(textwrap.fill(kept, 80, subsequent_indent="  ", break_on_hyphens=False))
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

    def _self_tests(self) -> None:
        """The MPU-6000's self-test of each board still in the sitting, one after the other
        (several: each under its serial), into every record's header (measurement.self_test).
        A board that vanishes or goes silent is waited for as in every other step
        (:meth:`_recover_unit`); in a sitting of several, one that does not come back leaves
        the sitting, named as lost during the self-test, and the others go on."""
        run = self.opts.schedule.self_test
        self.in_self_test = True
        try:
            for u in self.live:
                if u.lost is not None:  # left while an earlier board's self-test asked
                    continue
                with self._on(u):
                    if self.several:
                        self.op.say(f"{u.serial}:")
                    self_test(u.board, self.op, YES_MAX_ATTEMPTS, self._self_test_back(u), run)
        finally:
            self.in_self_test = False

    def _self_test_back(self, unit: Unit) -> Callable[[Exception], bool]:
        """How the self-test of ``unit`` waits for its board (:meth:`_recover_unit`): True
        when it is back (the self-test is tried again), False when it left the sitting."""

        def recover(exc: Exception) -> bool:
            self._recover_unit(unit, exc, measuring=False)
            return unit.lost is None

        return recover

    def _warm_up(self) -> None:
        """The warm-up (method.md §5 step 3), recorded as ``SERIAL_warmup.txt``: one attitude,
        the chip temperature rising — the thermal calibration's first ramp
        (``python3 -m host thermal``). Any key skips the rest of the wait (nothing recorded)."""
        s = self.opts.schedule.warmup_s
        warmed = record_path(self.out_dir, self.serial, WARMUP_NAME).exists()
        if s <= 0 or (
            self.opts.keeps_records and self.done and screens.no_warm_up(self.op, warmed)
        ):
            return
        op = self.op
        op.say(screens.warm_up_line(s, self.opts.yes))
        tick = screens.warm_up_progress(op, s)
        self.in_warm_up = True  # stays set if Ctrl+C ends the session here
        units = self.live
        try:
            acqs = acquire_boards([u.board for u in units], s, tick, op.key_pressed)
        except MeasurementAborted:
            self.in_warm_up = False
            op.end_progress()
            op.say("Warm-up ended by a key (not recorded).")
            return
        except BoardFailed as failed:
            self.in_warm_up = False
            self._warm_up_failed(units[failed.index], failed.error)
            return
        self.in_warm_up = False
        op.end_progress()
        for u, acq in zip(units, acqs, strict=True):
            with self._on(u):
                self._keep_warm_up(acq)

    def _warm_up_failed(self, unit: Unit, exc: Exception) -> None:
        """The warm-up of ``unit``'s board failed (and so of every board): not recorded; a
        board that vanished is waited for."""
        if not isinstance(exc, (LinkLost, LinkTimeout, BoardReset, SensorFault)):
            raise exc
        self.op.end_progress()
        on = f"{unit.serial}: " if self.several else ""
        self._warn(f"the warm-up is not recorded: {on}{exc}")
        if isinstance(exc, (LinkLost, LinkTimeout)):
            self._recover_unit(unit, exc, measuring=False)

    def _keep_warm_up(self, acq: Acquisition) -> None:
        """The warm-up of the board in hand written as its ``SERIAL_warmup.txt``."""
        if len(acq.t_us) >= 2:
            rec = self._record(WARMUP_NAME, acq, {"kind": "warmup"})
            path = self._keep_earlier(WARMUP_NAME)
            write_record(path, rec)  # not a calibration record: not in self.done
            self.op.say(f"Warm-up done; recorded {path}")
        else:
            self.op.say("Warm-up done.")

    # ---- results -------------------------------------------------------------------------
    def _results(self) -> DialogueResult:
        """Compute and write the results from every record of this serial in the output
        directory (:func:`host.calib.publish.compute_and_write`, as ``calibrate --from-dir``)."""
        op = self.op
        missing = [
            n for n in STATIC_NAMES if not record_path(self.out_dir, self.serial, n).exists()
        ] if not self.opts.planning.plan.startswith("poses") else []  # fmt: skip
        if missing:
            raise ResumableError(
                self._resume_hint(
                    f"the results need the six static records; missing {', '.join(missing)}"
                )
            )
        session = read_session(self.out_dir, self.serial)
        try:
            pub = compute_and_write(session, self.out_dir, self.opts.compute, note=op.say)
        except RecordCheckError as exc:
            name = failed_record(exc, self.serial)
            if name is None:
                raise
            raise ResumableError(
                said_with_command(
                    f"{exc}; measure {name} again (the other records are kept) with:",
                    self.command_words(then=("--redo", name)),
                )
            ) from None
        pdf = f", {pub.pdf_path}" if pub.pdf_path is not None else ""
        op.say(f"Results: {pub.report_path} and {pub.json_path}{pdf}")
        show_result(pub, self.opts.json)
        if self.after_publish is not None:  # calibrate archives the result
            op.say(self.after_publish(self.out_dir, session))
        if self.opts.planning.plan == "adaptive":  # whether its target was met, as fitted
            op.say(target_line(pub.result.parameters, self.opts.planning.target))
        op.say(verdict_line(pub.result, pub.report_path, pub.records_dir))  # the last lines
        return DialogueResult(
            self.out_dir, list(self.accepted), pub.result, (pub.report_path, pub.json_path)
        )


# --------------------------------------------------------------------------- entry points


def run_dialogue(
    options: DialogueOptions,
    console: Console | None = None,
    port_factory: Callable[[str], serial.SerialBase] | None = None,
    after_publish: AfterPublish | None = None,
) -> int:
    """Run the live calibration dialogue; the runner of ``python3 -m host calibrate --port``.

    ``options``: what ``calibrate`` was told (:func:`host.cli.calibrate.dialogue_options`).
    ``console``: the terminal (default: the real one; tests pass a
    :class:`host.dialogue.console.ScriptedConsole`). ``port_factory(url)``: opens the port
    (default :func:`host.board.link.open_port`). ``after_publish(out_dir, session)``: called
    once the result files are written, returns the line to say (``calibrate`` archives the
    result: :func:`host.cli.calibrate.archive_line`). Returns the exit status: 0 every value
    within tolerance, 1 some outside, 130 aborted with Ctrl+C. UserError for what the user
    can fix.
    """
    opts, note = with_port(options.check())
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
            session = CalibrationDialogue(opts, con, port_factory, after_publish)
            outcome = session.run()
            return 0 if outcome.all_passed else 1
    except KeyboardInterrupt as exc:
        return _aborted(exc, con, session)
    except (UserError, OSError) as exc:
        raise _ended_on_error(exc, session) from None
    finally:
        if session is not None:
            for u in session.units:
                u.board.close()
                if u.sitting is not None:
                    u.sitting.release()
        if term is not None:
            term.close()


def with_port(opts: DialogueOptions) -> tuple[DialogueOptions, str | None]:
    """``opts`` with the port to use: the one given, else the first board found, else the
    virtual board (at full speed with --yes: nobody watches); and what to say about it."""
    if opts.port:
        return opts, None
    port, note = default_port()
    if port == "sim://" and opts.yes:  # nobody watches: as fast as it computes
        port = "sim://?speed=max"
        note = f"{note}; at full speed with --yes (--port sim:// shows it in real time)"
    return replace(opts, port=port), note


def _aborted(exc: KeyboardInterrupt, con: Console, session: CalibrationDialogue | None) -> int:
    """Ctrl+C (or SIGTERM, SIGHUP): what is discarded, the command that continues; the exit
    status of the signal."""
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
            con.say(session._resume_hint(first=0))
    return exc.exit_status if isinstance(exc, EndedBySignal) else 130


def _ended_on_error(
    exc: UserError | OSError, session: CalibrationDialogue | None
) -> UserError | OSError:
    """The error a session ends on: one that ended it after records were accepted (disk
    full, sensor failed, board gone) says how to continue with them."""
    told = isinstance(exc, (ResumableError, DirectoryBusy))  # it says what to do
    if session is None or not session.serial or told:
        return exc
    text = str(exc) if isinstance(exc, UserError) else str(write_error(exc.filename, exc))
    return UserError(session._resume_hint(text))
