"""One measurement of the dialogue: its acquisition through the board driver, the record it
becomes with its ``#`` header, and the checks of that one record (method.md §5).

The board — HELLO, commands, clock feeding, acquisition and units — is
:class:`host.board.driver.Board` (port → :class:`host.board.link.Link`, every byte into an
IMUCAP01 capture ``SERIAL_session.cap`` beside the records → frames → counts → m/s², °/s, °C).

Acquisition window, on device time: at the start beep the host sends PING; the board's PONG
gives its ``t_us`` at that moment (``device_t_us_beep``), and the measurement holds exactly the
samples whose device time lies in ``[beep, beep + duration)`` — whatever is still in flight
from before the beep is dropped by its time stamp, however the reads are chunked and however
loaded the host is. Time column: device time, ms: ``t_us`` unwrapped (32-bit wrap) minus the
``t_us`` of the first sample of the window (the device clock, not an assumed 50 Hz). Every
sample read also feeds a live minimum-delay clock estimate (:class:`host.timing.clock.LiveClock`,
restarted when the board resets); the record's ``#`` header (:func:`record_header`) holds the
device→host mapping: ``device_t_us_start``, ``host_ns_start_beep``, ``host_ns_first_sample``
(host ``time.monotonic_ns``), and from the live estimate ``clock_host_ns_at_start`` (the first
sample's mapped host time), ``clock_skew_ppm``, ``clock_points``, ``clock_latency_median_us``,
``clock_floor_spread_us``. The session's capture file allows the best offline fit later.

Losses: sequence gaps between the frames of a measurement (frames lost on the link) plus
samples the firmware flagged MISSED are counted, reported ("3 samples lost in x_up") and
written into the record header; above the dialogue's loss limit
(:data:`host.dialogue.options.LOSS_LIMIT`) the program proposes to repeat
(:func:`loss_problems`).

The MPU-6000's self-test at the start of a sitting (:func:`self_test`) is a measurement too:
its outcome goes into the header of every record of the sitting (``self_test``,
``self_test_change_pct``, ``self_test_note``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np
import serial

from host.board.acquisition import (
    Acquisition,
    BoardFailed,
    BoardReset,
    MeasurementAborted,
    SensorFault,
)
from host.board.driver import Board, acquire_boards
from host.board.link import LinkLost, LinkTimeout
from host.dialogue.console import Questions
from host.dialogue.screens import measurement_progress
from host.errors import RecordCheckError, ResumableError, UserError
from host.model.geometry import DIALOGUE_HEADING_DEG
from host.session.checks import check_orientation
from host.session.directory import SIMULATED_BOARD, SIMULATED_SCHEMES, Session
from host.session.method import record_stats
from host.session.observations import build_observations
from host.session.records import HEADING_KEY, Record
from host.wire.frames import bus_meta
from host.wire.selftest import NOT_RUN, SelfTest

#: the placement every prompt asks for (:func:`host.dialogue.screens.place_prompt`), written in
#: the header of every static and turn record: the heading the model then reads
PLACED = {HEADING_KEY: f"{DIALOGUE_HEADING_DEG:g}"}

# --------------------------------------------------------------------------- acquisition


def acquire(
    boards: Sequence[Board],
    op: Questions,
    name: str,
    seconds: float,
    title: str,
    *,
    yes: bool,
    recover: Callable[[int, Exception], None],
    resume_hint: Callable[[str], str],
    enough: Callable[[np.ndarray, float], bool] | None = None,
    who: Sequence[str] = (),
    drop: Callable[[int, str], None] | None = None,
) -> list[Acquisition] | None:
    """Beep, record ``seconds`` of device time on every board of ``boards`` at once with a
    progress line (or less, when ``enough(counts, elapsed_s)`` says so, one board only:
    :meth:`host.board.driver.Board.acquire`), beep. None when the measurement was aborted
    (Esc) or a board vanished/restarted (``recover(k, exc)`` waits for board ``k`` to come
    back): nothing of it is kept, the caller proposes it again. A sensor fault asks whether
    to measure again (``--yes``: no): then ResumableError with ``resume_hint()`` — or, in a
    sitting of several boards (``who``: their serials), ``drop(k, why)`` takes that board out
    of the sitting and the others measure again."""
    assert boards[0].info is not None
    op.beep()
    op.say(f"{title} {name}: {seconds:g} s" + ("" if yes else " (Esc aborts)"))
    tick = measurement_progress(op, name, seconds, boards[0].info)
    try:
        acqs = acquire_boards(boards, seconds, tick, op.escape_pressed, enough)
    except MeasurementAborted:
        op.end_progress()
        op.beep()
        op.say(f"Measurement of {name} aborted (Esc): nothing kept. Again:")
        return None
    except BoardFailed as failed:
        on = f"{who[failed.index]}: " if who else ""
        _board_failed(failed.index, failed.error, op, name, on, yes=yes, recover=recover,
                      resume_hint=resume_hint, drop=drop)  # fmt: skip
        return None
    op.end_progress()
    op.beep()
    empty = [k for k, a in enumerate(acqs) if len(a.t_us) < 2]
    if empty:
        on = f" from {', '.join(who[k] for k in empty)}" if who else ""
        op.say(f"!!! no samples received for {name}{on}; measuring it again")
        return None
    return acqs


def _board_failed(
    k: int,
    exc: Exception,
    op: Questions,
    name: str,
    on: str,
    *,
    yes: bool,
    recover: Callable[[int, Exception], None],
    resume_hint: Callable[[str], str],
    drop: Callable[[int, str], None] | None,
) -> None:
    """Board ``k`` (``on``: its serial and a colon, in a sitting of several) failed during
    the measurement of ``name`` with ``exc``: waited for, measured again, or (a sensor
    fault) stopped or dropped."""
    if isinstance(exc, (LinkLost, LinkTimeout)):
        recover(k, exc)
        op.say(f"Measuring {name} again.")
        return
    if not isinstance(exc, (BoardReset, SensorFault)):
        raise exc  # another board's error the dialogue cannot help (a wrong firmware)
    op.end_progress()
    if isinstance(exc, BoardReset):
        op.say(f"!!! {on}{exc}: the measurement of {name} is discarded; measuring it again")
        return
    op.beep()
    op.say(f"!!! {on}{exc}")
    op.say(f"!!! the measurement of {name} is discarded")
    if drop is not None:  # a sitting of several: the others go on without it
        if yes or not op.yes_no(f"Measure again <Y> or drop {on[:-2]} from the sitting <N>?",
                                True):  # fmt: skip
            drop(k, f"{exc}")
        return
    if yes or not op.yes_no("Measure again <Y> or stop <N>?", True):
        raise ResumableError(resume_hint(f"{name}: {exc}")) from None


def reconnect(
    board: Board,
    op: Questions,
    exc: Exception,
    *,
    measuring: bool,
    yes: bool,
    limit_s: float | None,
    resume_hint: Callable[[str], str],
) -> None:
    """The board vanished or went silent (``exc``): say so, re-open the port every second until
    it is back. ResumableError (with ``resume_hint()``) after ``limit_s`` s (None: no limit) or
    when the operator gives up (Esc); UserError when it comes back with the wrong firmware."""
    op.end_progress()
    op.beep()
    op.say(f"!!! {exc}")
    if measuring:
        op.say("The measurement in progress is discarded; accepted records are kept.")
    op.say(
        "Waiting for the board to come back (trying every second"
        + ("; Esc gives up, Ctrl+C aborts)" if not yes else ")")
    )
    start = time.monotonic()
    attempt = 0
    while True:
        attempt += 1
        try:
            info = board.reopen()
            break
        except UserError:
            raise  # wrong firmware after the reconnect: nothing to wait for
        except (serial.SerialException, OSError, LinkLost, LinkTimeout):
            pass
        if limit_s is not None and time.monotonic() - start > limit_s:
            raise ResumableError(resume_hint(f"the board did not come back within {limit_s:.0f} s"))
        if op.countdown(1.0, f"  waiting for the board (attempt {attempt})", False):
            raise ResumableError(resume_hint("gave up waiting for the board"))
    op.say(f"The board is back: {info.describe()}")


def self_test(
    board: Board,
    op: Questions,
    attempts: int,
    recover: Callable[[Exception], bool],
    run: bool = True,
) -> None:
    """The MPU-6000's self-test (:meth:`host.board.driver.Board.self_test`) with the cube
    still, shown line by line; a failure is announced (it fails the calibration). Without a
    verdict because the cube moved, the operator may repeat it, up to ``attempts`` times.
    ``recover(exc)`` waits for a board that vanished: True, it is back (the self-test is tried
    again); False, it left the sitting (nothing more is asked of it).
    ``run`` False (``--no-self-test``): not run, and every record's header says so."""
    if not run:
        board.self_test_result = SelfTest(NOT_RUN, "skipped with --no-self-test", (), 0)
        op.say(board.self_test_result.lines()[0])
        return
    for attempt in range(1, attempts + 1):
        op.say("MPU-6000 self-test: keep the cube still (about 2 s)…")
        try:
            st = board.self_test()
        except (LinkLost, LinkTimeout) as exc:
            op.say(f"!!! the self-test is not recorded: {exc}")
            if not recover(exc):
                return
            continue
        for line in st.lines():
            op.say(line)
        if st.outcome == "fail":
            op.say("!!! the sensor fails its self-test: this calibration's verdict is FAIL")
        if st.outcome or "moved" not in st.reason:
            return
        if attempt == attempts or not op.yes_no(
            "Repeat the self-test <Y> or go on without it <N>?", True
        ):
            return


def capture_path(out_dir: Path, serial: str) -> Path:
    """The session's capture file: ``SERIAL_session.cap``, else the next free
    ``SERIAL_session_2.cap``, … (a resumed session never overwrites an earlier one)."""
    path = out_dir / f"{serial}_session.cap"
    k = 2
    while path.exists():
        path = out_dir / f"{serial}_session_{k}.cap"
        k += 1
    return path


# --------------------------------------------------------------------------- the record


def make_record(
    board: Board,
    serial: str,
    name: str,
    acq: Acquisition,
    extra: Mapping[str, str],
    session_start_ns: int,
) -> Record:
    """The record of an acquisition: the samples in physical units (m/s², °/s, °C), time in
    device ms, and its header (:func:`record_header`)."""
    accel, gyro, temp = board.physical(acq.counts)
    meta = record_header(board, serial, acq, extra, session_start_ns)
    return Record(name, acq.t_us / 1000.0, accel, gyro, temp, meta)


def record_header(
    board: Board,
    serial: str,
    acq: Acquisition,
    extra: Mapping[str, str],
    session_start_ns: int,
) -> dict[str, str]:
    """A live record's ``#`` header: the serial, ``extra`` (kind, turns…), the board, the
    counts of the acquisition, its start times and the device→host clock mapping."""
    assert board.info is not None
    meta: dict[str, str] = {"serial": serial, **extra}
    meta.update(board.info.meta())
    if board.self_test_result is not None:  # the MPU-6000's self-test of this sitting
        meta.update(board.self_test_result.meta())
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
            **session_time(board, acq, session_start_ns),
            "host_ns_start_beep": str(acq.beep_ns),
            "host_ns_first_sample": str(acq.first_ns),
            "time_mapping": "device_t_us_start (first sample) at host_ns_start_beep "
            "(time.monotonic_ns of the start beep); clock_*: live minimum-delay map",
            **board.clock_meta(acq.start_t_us),
            **bus_meta(acq.status_flags),
            "port": board.url,
            **(
                {"board": f"{SIMULATED_BOARD} {board.url}"}
                if board.url.startswith(SIMULATED_SCHEMES)
                else {}
            ),
            "capture": board.capture.path.name,
            "program": "python3 -m host calibrate (live)",
        }
    )
    return meta


def session_time(board: Board, acq: Acquisition, session_start_ns: int) -> dict[str, str]:
    """Record start time: ``power_on_s`` (device clock since the board's last reset,
    unwrapped; the workbench's time since power-on) and ``session_s`` (host monotonic
    clock since the program started at ``session_start_ns``), both s, as
    :data:`host.session.records.TIME_KEYS` says."""
    out = {"session_s": f"{(acq.beep_ns - session_start_ns) / 1e9:.3f}"}
    p = board.power_on_s(acq.start_t_us)
    if p is not None:
        out["power_on_s"] = f"{p:.3f}"
    return out


# --------------------------------------------------------------------------- checks


def loss_problems(name: str, acq: Acquisition, limit: float) -> list[str]:
    """The problem of a measurement that lost more than ``limit`` (a fraction) of its samples."""
    if acq.lost == 0 or acq.loss_fraction <= limit:
        return []
    return [
        f"{100 * acq.loss_fraction:.1f} % of the samples of {name} were lost "
        f"(limit {100 * limit:g} %)"
    ]


def static_problems(rec: Record, g: float, serial: str) -> list[str]:
    """The attitude check of a static record of unit ``serial`` (``g``: local gravity, m/s²)."""
    try:
        check_orientation(rec, record_stats(rec), g, f"{serial}_{rec.name}.txt")
    except UserError as exc:
        return [str(exc)]
    return []


def over_range(acq: Acquisition, rec: Record, alarm_counts: int) -> tuple[int, float]:
    """Gyro samples of a turn at or beyond ``alarm_counts`` (any axis), and the peak rate, °/s."""
    gyro_counts = np.abs(acq.counts[:, 4:7]) if len(acq.counts) else np.zeros((0, 3))
    over = int(np.count_nonzero(np.any(gyro_counts >= alarm_counts, axis=1)))
    peak = float(np.abs(rec.gyro).max()) if len(rec) else 0.0
    return over, peak


def turn_problems(
    rec: Record,
    g: float,
    serial: str,
    statics: Mapping[str, Record],
    out_dir: Path,
    turns: int,
    latitude_deg: float,
) -> list[str]:
    """The attitude check of a turn record of unit ``serial``, then, with ``statics``
    already measured, the engine's angle check with their bias (problems of this record
    only); a turn that starts or ends in motion is one too (the fit would keep it with its
    angle an unknown: measured again at rest, it gives the gyro scale)."""
    file_name = f"{serial}_{rec.name}.txt"
    problems: list[str] = []
    try:
        check_orientation(rec, record_stats(rec), g, file_name)
    except RecordCheckError as exc:
        problems.append(str(exc))
    if statics:
        sess = Session(serial, {**statics, rec.name: rec}, out_dir)
        try:
            obs, _ = build_observations(sess, g, turns=turns, latitude_deg=latitude_deg)
            moving = next((o.in_motion for o in obs if o.record == rec.name), "")
            if moving:
                problems.append(
                    f"{file_name}: the turn record {moving}: its angle is not known, so it "
                    "gives no gyro scale; rest the cube before the first beep and after the turn"
                )
        except RecordCheckError as exc:
            if exc.file_name == file_name:  # a problem of this record, not of the statics
                problems.append(str(exc))
        except UserError:
            pass
    return problems
