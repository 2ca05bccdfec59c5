"""What the dialogue shows the operator: the opening lines, the prompts, the progress line of a
measurement, and the summaries of each record and stage (method.md §5).

Text only: each function writes on a :class:`host.dialogue.console.Questions` (``op``) or
returns the line to show; what to measure, keep or repeat is decided in
:mod:`host.dialogue.flow`. Units as printed: m/s², °/s, °C, s.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from host.board.acquisition import Acquisition
from host.board.driver import BoardInfo
from host.calib.calibration import Stage1
from host.dialogue.console import Questions
from host.model.geometry import placement_words
from host.session.method import record_stats, trapezoid_integral
from host.session.records import Record
from host.wire import sensor
from host.workbench.stopping import StaticRule

AXIS_WORDS = {"x": "X", "y": "Y", "z": "Z"}
CHANNELS = ("Ax", "Ay", "Az", "Gx", "Gy", "Gz", "temp")
#: the unit of each of :data:`CHANNELS` as shown
CHANNEL_UNITS = ("m/s²", "m/s²", "m/s²", "°/s", "°/s", "°/s", "°C")

#: a measurement's progress callback: (elapsed s, sums of the counts so far, samples so far)
Tick = Callable[[float, np.ndarray, int], None]


# --------------------------------------------------------------------------- prompts


def show_opening(op: Questions, url: str) -> None:
    """The title, the keys, the first instruction, the port being opened."""
    op.say("IMU CALIBRATION BENCH — MPU-6000 (APM 2.6): live calibration, method.md §5")
    op.say(
        "Ctrl+C ends the session (accepted records are kept, the command to resume is "
        "printed); Esc aborts only the current measurement"
    )
    op.say("Level the base. Connect the unit by USB (the board's green LED lights).")
    op.say(f"Opening {url} ...")


def _up(axis: str, side: str) -> np.ndarray:
    return np.eye(3)["xyz".index(axis)] * (1.0 if side == "up" else -1.0)


def place_prompt(axis: str, side: str) -> str:
    """The question before a static measurement: which axis up or down (``side``), and how the
    cube sits against the fence (:data:`host.model.geometry.DIALOGUE_HEADING_DEG`, the heading
    the record's header carries)."""
    where = "up" if side == "up" else "down"
    return (
        f"Put the cube on the base with {AXIS_WORDS[axis]} {where}, "
        f"{placement_words(_up(axis, side))}. Press any key."
    )


def turn_place_prompt(axis: str) -> str:
    """The question before a turn: the cube with ``axis`` up, against the fence (the ruler) at
    the dialogue's placement heading; the turn starts and ends there."""
    return f"Put the cube {AXIS_WORDS[axis]} up, {placement_words(_up(axis, 'up'))}. Press any key."


def get_ready_line(n: int, direction: str, window_s: float) -> str:
    """What to turn (``n`` turns, ``direction`` ccw/cw) within the window, s."""
    words = "counter-clockwise" if direction == "ccw" else "clockwise"
    return (
        f"Get ready to turn {n} turn{'s' if n > 1 else ''} {words} (seen from above) "
        f"within {window_s:g} s, between the beeps."
    )


def turn_window_line(window_s: float) -> str:
    """How a turn is recorded: its window, s, and what the operator does."""
    return (
        f"Each turn is recorded for {window_s:g} s between two beeps, the same for both "
        "directions. Turn by hand about the vertical and bring the cube back to the ruler."
    )


def stops_when_enough_line(rule: StaticRule) -> str:
    """--plan adaptive: how long a face is measured (the rule of
    :class:`host.workbench.stopping.StaticRule`)."""
    return (
        f"Each face ends when its mean is precise enough (gyro σ ≤ {rule.gyro_sigma:.2g} °/s, "
        f"accel σ ≤ {rule.accel_sigma:.2g} m/s²): {rule.min_s:g} to {rule.max_s:g} s."
    )


def operator_time_line(spent_s: float, fixed_s: float) -> str:
    """--plan adaptive: the operator's time its records cost (placing, settling, measuring,
    turning: :meth:`host.workbench.adaptive.AdaptivePlan.cost`), s, beside the fixed plan's
    of the same faces and turns (``fixed_s``, :func:`host.workbench.adaptive.fixed_plan_s`)."""
    return (
        f"Adaptive plan: about {spent_s:.0f} s of your time on its records this sitting\n"
        f"  (the fixed plan: about {fixed_s:.0f} s)."
    )


def adaptive_resumed_line(kept: int, added: int) -> str:
    """--plan adaptive --resume: the plan goes on from the ``kept`` records, ``added`` of
    them the planner's (``--max-extra`` counts them)."""
    return f"Adaptive plan: goes on from the {kept} records kept, {added} of them the planner's."


def closing_line(first: str) -> str:
    """The closing check's announcement: the first attitude (``first``) once more."""
    return (
        f"Closing check: {first} once more (its difference from the first measurement "
        "shows the drift over the session; --no-closing leaves it out)."
    )


def warm_up_line(seconds: float, yes: bool) -> str:
    """The warm-up's instruction (its length in minutes or seconds)."""
    span = f"{seconds / 60:.0f} minutes" if seconds >= 120 else f"{seconds:.0f} seconds"
    return (
        f"Keep the unit powered about {span} (warm-up; recorded for the thermal "
        "calibration)." + ("" if yes else " Press any key when ready (skips it).")
    )


def no_warm_up(op: Questions, warmed: bool) -> bool:
    """--resume/--redo with records kept: no warm-up now (says so; True). ``warmed``: a
    warm-up ran to its end before the kept records (its record is in the directory); else it
    was ended by a key or not made, and the line does not claim a warm unit."""
    if warmed:
        op.say(
            "No warm-up: the kept records were measured on a warm unit (if it was off since, "
            "let it warm up before the next measurement)"
        )
    else:
        op.say(
            "No warm-up: records are kept, and no whole warm-up was recorded before them (it "
            "was ended by a key or not made): let the unit warm up before the next measurement"
        )
    return True


def kept_accumulation(op: Questions, durations: list[float]) -> float:
    """--resume/--redo: the accumulation time of the kept static records (their median
    length, whole seconds), said, not asked again."""
    seconds = float(round(float(np.median(durations))))
    op.say(f"Accumulation time {seconds:g} s per orientation, as the kept records "
           "(--static-seconds S changes it)")  # fmt: skip
    return seconds


# --------------------------------------------------------------------------- progress lines


def warm_up_progress(op: Questions, seconds: float) -> Tick:
    """The warm-up's countdown, m:ss left of ``seconds``."""

    def tick(elapsed: float, _sums: np.ndarray, _k: int) -> None:
        m, sec = divmod(int(max(seconds - elapsed, 0.0) + 0.999), 60)
        op.progress(f"  warm-up: {m}:{sec:02d}")

    return tick


def whole_parts(width: int, *parts: str) -> str:
    """The parts, two spaces apart, as many as fit in ``width`` whole (a progress line is
    redrawn in place: it must not wrap, and a number cut short would read as another)."""
    line = parts[0]
    for part in parts[1:]:
        if len(line) + 2 + len(part) > width:
            break
        line += "  " + part
    return line


def measurement_progress(op: Questions, name: str, seconds: float, info: BoardInfo) -> Tick:
    """The progress line of measurement ``name`` (``seconds`` of device time): a bar, the time,
    and the means so far with their units (m/s², °/s, two decimals: the line keeps to 80
    columns) — or, for a turn, the angle turned so far about the up
    axis, from the mean rate between two ticks (rough: the bias is not removed), shown to help
    the operator."""
    a_scale = sensor.G0 / info.accel_lsb_per_g
    g_scale = 1.0 / sensor.GYRO_LSB_PER_DPS[info.gyro_fs_sel]
    up_axis = "xyz".find(name[0])  # a pose (pose_01): none
    last = {"t": 0.0, "k": 0, "sum": 0.0, "angle": 0.0}

    def tick(elapsed: float, sums: np.ndarray, k: int) -> None:
        frac = min(1.0, elapsed / seconds) if seconds > 0 else 1.0
        bar = "#" * int(frac * 10) + "-" * (10 - int(frac * 10))
        head = f"{name} [{bar}] {elapsed:5.1f}/{seconds:g} s"
        if k == 0:
            op.progress(head)
            return
        m = sums / k
        if name.endswith(("_ccw", "_cw")) and up_axis >= 0:
            s_up = float(sums[4 + up_axis])
            if k > last["k"]:
                rate = (s_up - last["sum"]) / (k - last["k"]) * g_scale
                last["angle"] += rate * (elapsed - last["t"])
            last.update(t=elapsed, k=k, sum=s_up)
            op.progress(f"{head}  turned {last['angle']:+5.0f}° about {name[0].upper()}")
        else:
            accel = "A " + " ".join(f"{v * a_scale:+.2f}" for v in m[0:3]) + " m/s²"
            gyro = "G " + " ".join(f"{v * g_scale:+.2f}" for v in m[4:7]) + " °/s"
            op.progress(whole_parts(op.columns - 1, head, accel, gyro))

    return tick


# --------------------------------------------------------------------------- summaries


def show_table(op: Questions, rec: Record) -> None:
    """A static record's mean and standard deviation per channel, under a row of units."""
    st = record_stats(rec)
    mean = np.concatenate([st.accel_mean, st.gyro_mean, [rec.temp.mean()]])
    std = np.concatenate([st.accel_std, st.gyro_std, [rec.temp.std(ddof=1)]])
    op.say(f"{rec.name}: {len(rec)} samples over {rec.duration_s:.2f} s")
    op.say("      " + "".join(f"{c:>10}" for c in CHANNELS))
    op.say("unit  " + "".join(f"{u:>10}" for u in CHANNEL_UNITS))
    dec = (4, 4, 4, 3, 3, 3, 1)
    op.say("mean  " + "".join(f"{v:>10.{d}f}" for v, d in zip(mean, dec, strict=True)))
    op.say("std   " + "".join(f"{v:>10.{d + 1}f}" for v, d in zip(std, dec, strict=True)))


def show_integrals(op: Questions, rec: Record) -> None:
    """A turn's six integrals over the record (trapezoid rule): m/s and °."""
    ia = trapezoid_integral(rec.t_ms, rec.accel)
    ig = trapezoid_integral(rec.t_ms, rec.gyro)
    op.say(f"Integrals over {rec.duration_s:.2f} s (trapezoid rule):")
    op.say("  " + "  ".join(f"∫{c} {v:+10.4f} m/s" for c, v in zip(CHANNELS[:3], ia, strict=True)))
    op.say("  " + "  ".join(f"∫{c} {v:+10.3f} °" for c, v in zip(CHANNELS[3:6], ig, strict=True)))


def range_alarm(over: int, peak_dps: float, range_dps: int) -> str:
    """The problem of a turn with ``over`` gyro samples at the end of the range."""
    return (
        f"RANGE ALARM: {over} gyro samples at or beyond ±{range_dps} "
        f"°/s (peak {peak_dps:.1f} °/s): the turn was too fast, turn more slowly"
    )


def peak_rate_line(peak_dps: float, range_dps: int) -> str:
    """A turn's peak rate against the working range."""
    return f"  peak rate {peak_dps:.1f} °/s (working range ±{range_dps} °/s)"


def loss_line(name: str, acq: Acquisition) -> str:
    """The samples lost in measurement ``name``: on the link, by the firmware, in %."""
    return (
        f"{acq.lost} samples lost in {name} ({acq.lost_frames} frames lost on the link, "
        f"{acq.missed} missed by the firmware; {100 * acq.loss_fraction:.2f} %)"
    )


def show_stage1(op: Questions, s1: Stage1, g: float) -> None:
    """The stage-1 constants (method.md §3) and how far the accel bias estimates disagree."""
    c = s1.constants()
    op.say(f"Stage 1 constants (method.md §3, g = {g:.5f} m/s²):")

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


def closing_difference(opening: Record, closing: Record) -> str:
    """The closing check's line: closing − opening means (m/s², °/s) and the time between."""
    sa, sb = record_stats(opening), record_stats(closing)
    t = [float(r.meta.get("session_s", "nan")) for r in (opening, closing)]
    gap = f" {(t[1] - t[0]) / 60:.1f} min later" if all(map(math.isfinite, t)) else ""
    return (
        f"Closing − opening{gap}: accel "
        + " ".join(f"{v:+.4f}" for v in sb.accel_mean - sa.accel_mean)
        + " m/s², gyro "
        + " ".join(f"{v:+.4f}" for v in sb.gyro_mean - sa.gyro_mean)
        + " °/s (x y z)"
    )
