"""An independent session: six static faces, hand turns each way about each axis and the
closing X-up, written in the project's record format with the truth beside it.

``simulate(SessionSpec(seed=…, effect=…))`` returns the records in memory (with their
noiseless true inputs, for the tests); ``write_session(directory, spec)`` writes
``SERIAL_name.txt`` files and ``truth.json`` (not a record file: the host skips it).

The plan follows method.md §4–§5 and the dialogue: ``warmup_s`` (10 min) after power-on,
the statics x_up … z_dn (``static_s`` each), the turns x_ccw, x_cw … z_cw (``turns`` whole
turns in the fixed window, made as quarter turns with rests: before, between and after), then
x_up again (``x_up_2``).
The operator takes 15–25 s between records. Headings: every record is placed at heading 0
(the reference axis along the fence) or, with ``headings='random'``, at a random multiple of
90°; ``record_heading`` writes it in the header as ``placement_heading_deg``.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from tests.independent import physics as ph
from tests.independent.effects import EFFECTS, Effect, Signals
from tests.independent.recordfile import record_text, write_record_file
from tests.independent.truth import BaseTruth, Geometry, random_base

#: header key of the placement heading, ° counter-clockwise (seen from above) from the fence to
#: the record's reference axis (the first of +x, +y, +z not along up), at the record's start
HEADING_KEY = "placement_heading_deg"
#: the fixed windows of method.md §4, s
TURN_WINDOW_S = {1: 7.0, 2: 12.0, 3: 15.0}
STATICS = ("x_up", "x_dn", "y_up", "y_dn", "z_up", "z_dn")
TURNS = ("x_ccw", "x_cw", "y_ccw", "y_cw", "z_ccw", "z_cw")


@dataclass(frozen=True)
class SessionSpec:
    """What to simulate. Noise densities are one-sided white densities (unit/√Hz)."""

    seed: int
    effect: str = "none"
    serial: str = "IND01"
    static_s: float = 10.0
    turns: int = 2
    closing: bool = True
    #: the first record starts this long after power-on (the dialogue's warm-up), s
    warmup_s: float = 600.0
    headings: str = "zero"  # "zero" | "random"
    record_heading: bool = False
    accel_density: float = 0.0020  # m/s²/√Hz -> 0.010 m/s² per sample at 50 Hz
    gyro_density: float = 0.0050  # °/s/√Hz -> 0.025 °/s per sample
    temp_noise_c: float = 0.02
    quantise: bool = True
    latitude_deg: float = 55.75
    #: how the hand turns: "quarters" (quarter turns with rests between them) or
    #: "continuous" (the method's bench: the whole turns in one motion, rests only at its
    #: start and end, at the same heading; :func:`tests.independent.physics.continuous_turn`)
    turn_motion: str = "quarters"
    #: the hand's turn-angle error: each turn record is long by a normal draw of this std, °
    #: (0: every turn exactly 360°·n)
    turn_angle_sd_deg: float = 0.0
    height_m: float = 150.0
    #: records measured after the plan (a face or a turn again: 'y_dn_2', 'z_ccw_2'), each
    #: as long as its kind's records in the plan, or (name, seconds) for a static of its own
    #: length, or an :class:`Extra` (an attitude off the faces, turns at another pace)
    extra: tuple[str | tuple[str, float] | Extra, ...] = ()
    #: turn records cut in motion: (record, 'starts' | 'ends', degrees): the record starts
    #: after the hand has turned that many degrees, or ends that many degrees before it stops
    #: (the beep came late, or early); the sensor and the other records are unchanged
    turn_cut: tuple[tuple[str, str, float], ...] = ()


@dataclass(frozen=True)
class Extra:
    """A record measured after the plan, of a kind the plan does not hold.

    ``name``: its name ('tilt_45_3', 'y_ccw_2'); ``kind``: 'static' or 'turn'; ``up``: the body
    direction held up (a unit vector; a 45° attitude rests on a wedge whose seat is square: no
    face lean), None for the face its name says; ``seconds``: a static's length (0: the plan's
    ``static_s``); ``pace``: a turn made this many times as fast as the hand turns in the plan
    (its quarter turns last ``1/pace`` times as long; a slower turn gets a window ``1/pace``
    times as long, so that the same whole turns fit); ``heading_deg``: the operator places it
    at this heading and writes it in its header (None: as the plan's records)."""

    name: str
    kind: str = "static"
    up: tuple[float, float, float] | None = None
    seconds: float = 0.0
    pace: float = 1.0
    heading_deg: float | None = None


@dataclass
class SimRecord:
    """One record: what the file holds plus the true inputs behind it."""

    name: str
    meta: dict[str, str]
    t_ms: np.ndarray
    accel: np.ndarray
    gyro: np.ndarray
    temp_c: np.ndarray
    true_force: np.ndarray  # (N, 3) m/s², body axes
    true_rate: np.ndarray  # (N, 3) °/s, body axes
    heading_deg: float
    turn_deg: float = 0.0  # signed turned angle about the plate's normal (turn records)


@dataclass
class SimSession:
    spec: SessionSpec
    base: BaseTruth
    geometry: Geometry
    effect: Effect
    g: float
    temp: ph.TempModel = field(default_factory=ph.TempModel)
    records: list[SimRecord] = field(default_factory=list)

    def truth(self) -> dict[str, Any]:
        """The truth file's content (JSON-able)."""
        geo = self.geometry
        return {
            "format": "independent-sim truth v1",
            "spec": asdict(self.spec),
            "g": self.g,
            "constants": self.base.constants(),
            "effect": {"name": self.effect.name, **self.effect.params},
            "geometry": {
                "plate_tilt_rad": geo.plate_tilt_rad,
                "plate_azimuth_rad": geo.plate_azimuth_rad,
                "face_lean_rad": {k: v.tolist() for k, v in geo.face_lean.items()},
                "turn_lean_rad": {k: v.tolist() for k, v in geo.turn_lean.items()},
                "record_lean_rad": {k: v.tolist() for k, v in geo.record_lean.items()},
                "lever_arm_m": geo.lever_arm_m.tolist(),
            },
            "temperature": asdict(self.temp),
            "headings_deg": {r.name: r.heading_deg for r in self.records},
        }


def _face(name: str) -> str:
    """'x_dn' -> '-x', 'y_cw' -> '+y' (turns rest on their up face)."""
    axis, kind = name.split("_")[:2]
    return ("-" if kind == "dn" else "+") + axis


def _record(
    rng: np.random.Generator,
    s: SimSession,
    name: str,
    start_s: float,
    duration_s: float,
    heading_deg: float,
    extra: Extra | None = None,
) -> SimRecord:
    spec, geo, base = s.spec, s.geometry, s.base
    if extra is not None and extra.up is not None:
        face = "[" + ", ".join(f"{c:.6g}" for c in extra.up) + "]"
        kind, up = extra.kind, np.asarray(extra.up, dtype=float) / np.linalg.norm(extra.up)
        seat = up  # on a square wedge: no face lean
    else:
        face = _face(name)
        kind = "turn" if name.split("_")[1] in ("ccw", "cw") else "static"
        up = ph.axis_vector(face)
        seat = ph.seat_direction(up, geo.lean(face, kind, name))
    pace = extra.pace if extra is not None else 1.0
    n = int(round(duration_s * ph.FS_HZ))
    t_s = rng.uniform(0.0, 1.0 / ph.FS_HZ) + np.arange(n) / ph.FS_HZ
    r0 = ph.placement(seat, ph.reference_axis(up), 0.0)
    normal_b = r0.T @ np.array([0.0, 0.0, 1.0])  # the turn axis in body axes
    up_plate = ph.plate_to_room(geo.plate_tilt_rad, geo.plate_azimuth_rad).T @ [0.0, 0.0, 1.0]
    psi = np.full(n, math.radians(heading_deg))
    rate_up = acc_up = np.zeros(n)
    turn_deg = 0.0
    if kind == "turn":
        sign = 1 if name.split("_")[1] == "ccw" else -1
        prof: ph.TurnProfile | ph.ContinuousTurn
        if spec.turn_motion == "continuous":
            prof = ph.continuous_turn(rng, spec.turns, duration_s, sign, turn_s=4.4 / pace)
        else:
            prof = ph.hand_turn(rng, spec.turns, duration_s, sign, quarter_s=0.95 / pace)
        if spec.turn_angle_sd_deg > 0:  # drawn only then: the other sessions keep their stream
            err = float(rng.normal(0.0, spec.turn_angle_sd_deg))
            prof = replace(prof, scale=1.0 + err / (360.0 * spec.turns))
        psi = psi + np.radians(prof.angle_deg(t_s))
        rate_up, acc_up = prof.rate_dps(t_s), prof.accel_dps2(t_s)
        turn_deg = 360.0 * spec.turns * sign * prof.scale
    # gravity's up in the plate frame, seen from the turned cube: rotate by −ψ about the normal
    c, sn = np.cos(psi), np.sin(psi)
    w = np.column_stack(
        [c * up_plate[0] + sn * up_plate[1], -sn * up_plate[0] + c * up_plate[1],
         np.full(n, up_plate[2])]
    )  # fmt: skip
    force = s.g * (w @ r0)  # rows: (R0ᵀ w)ᵀ
    rate = rate_up[:, None] * normal_b[None, :]
    om = np.radians(rate)
    om_dot = np.radians(acc_up)[:, None] * normal_b[None, :]
    r = geo.lever_arm_m
    force = force + np.cross(om_dot, r) + np.cross(om, np.cross(om, r))
    pow_s = start_s + t_s
    temp, dtemp = ph.chip_temperature(pow_s, s.temp)
    sig = Signals(pow_s, pow_s - spec.warmup_s, temp, dtemp, force, rate, s.g)
    accel = force @ base.accel_matrix.T + base.accel_bias
    gyro = rate @ base.gyro_matrix.T + (force / s.g) @ base.g_sens.T + base.gyro_bias
    if s.effect.sensor is not None:
        da, dg = s.effect.sensor(sig)
        accel, gyro = accel + da, gyro + dg
    accel = accel + ph.white_noise(rng, spec.accel_density, (n, 3))
    gyro = gyro + ph.white_noise(rng, spec.gyro_density, (n, 3))
    temp_meas = temp + rng.normal(0.0, spec.temp_noise_c, n)
    if spec.quantise:
        accel, gyro = ph.quantise(accel, ph.ACCEL_LSB), ph.quantise(gyro, ph.GYRO_LSB)
        temp_meas = ph.quantise(temp_meas - ph.TEMP_OFFSET_C, ph.TEMP_LSB) + ph.TEMP_OFFSET_C
    meta = {
        "serial": spec.serial,
        "kind": kind,
        "up": face,
        "source": "independent simulator (tests/independent)",
        "power_on_s": f"{start_s:.3f}",
        "session_s": f"{start_s - spec.warmup_s + 10.0:.3f}",
    }
    if kind == "turn":
        meta.update(turns=str(spec.turns), direction=name.split("_")[1], window_s=f"{duration_s:g}")
    if spec.record_heading or (extra is not None and extra.heading_deg is not None):
        meta[HEADING_KEY] = f"{heading_deg:g}"
    return SimRecord(
        name, meta, t_s * 1000.0, accel, gyro, temp_meas, force, rate, heading_deg, turn_deg
    )


def cut_in_motion(r: SimRecord, end: str, missed_deg: float) -> SimRecord:
    """Turn record ``r`` cut where the hand has turned ``missed_deg`` since its motion began
    (``end`` 'starts') or has that many degrees still to turn (``end`` 'ends'): the samples
    before (after) are dropped, the time column restarts at the new first sample, the header's
    times and window follow, and ``turn_deg`` is the angle turned within what is left."""
    t_s = r.t_ms / 1000.0
    speed = np.linalg.norm(r.true_rate, axis=1)
    turned = np.concatenate([[0.0], np.cumsum(np.diff(t_s) * (speed[1:] + speed[:-1]) / 2)])
    total = float(turned[-1])
    if end == "starts":
        keep = slice(int(np.searchsorted(turned, missed_deg)), len(t_s))
    elif end == "ends":
        keep = slice(0, int(np.searchsorted(turned, total - missed_deg, "right")))
    else:
        raise ValueError("turn_cut: 'starts' or 'ends'")
    t0 = float(t_s[keep][0])
    left = float(turned[keep][-1] - turned[keep][0])
    meta = dict(r.meta)
    meta["power_on_s"] = f"{float(meta['power_on_s']) + t0:.3f}"
    meta["session_s"] = f"{float(meta['session_s']) + t0:.3f}"
    meta["window_s"] = f"{float(t_s[keep][-1] - t0) + 1.0 / ph.FS_HZ:.3f}"
    return replace(
        r, meta=meta, t_ms=r.t_ms[keep] - 1000.0 * t0, accel=r.accel[keep], gyro=r.gyro[keep],
        temp_c=r.temp_c[keep], true_force=r.true_force[keep], true_rate=r.true_rate[keep],
        turn_deg=math.copysign(left, r.turn_deg),
    )  # fmt: skip


def simulate(spec: SessionSpec) -> SimSession:
    """The records of one session (see the module docstring)."""
    if spec.effect not in EFFECTS:
        raise ValueError(f"unknown effect {spec.effect!r}; one of {', '.join(EFFECTS)}")
    if spec.headings not in ("zero", "random"):
        raise ValueError("headings: 'zero' or 'random'")
    if spec.turn_motion not in ("quarters", "continuous"):
        raise ValueError("turn_motion: 'quarters' or 'continuous'")
    # separate streams: the same seed gives the same unit, plan and noise whatever the effect
    rng = np.random.default_rng([spec.seed, 0])
    base = random_base(rng)
    effect = EFFECTS[spec.effect](np.random.default_rng([spec.seed, 1]))
    geo = Geometry()
    if effect.geometry is not None:
        effect.geometry(geo)
    temp = ph.TempModel(phase=float(rng.uniform(0.0, 2 * math.pi)))
    s = SimSession(spec, base, geo, effect, ph.local_g(spec.latitude_deg, spec.height_m), temp)
    plan = [(n, spec.static_s) for n in STATICS]
    window = TURN_WINDOW_S.get(spec.turns, 15.0 + 4.0 * (spec.turns - 3))
    plan += [(n, window) for n in TURNS]
    if spec.closing:
        plan.append(("x_up_2", spec.static_s))
    extras: dict[str, Extra] = {}
    for x in spec.extra:
        if isinstance(x, Extra):
            extras[x.name] = x
            turn = x.kind == "turn" or x.name.split("_")[1] in ("ccw", "cw")
            plan.append((x.name, window / min(x.pace, 1.0) if turn else x.seconds or spec.static_s))
            continue
        name, seconds = x if isinstance(x, tuple) else (x, spec.static_s)
        plan.append((name, window if name.split("_")[1] in ("ccw", "cw") else seconds))
    t = spec.warmup_s
    prev_end: float | None = None
    for name, dur in plan:
        heading = 0.0 if spec.headings == "zero" else 90.0 * int(rng.integers(0, 4))
        noted = extras[name].heading_deg if name in extras else None
        heading = heading if noted is None else noted  # drawn all the same: the same stream
        if effect.before_record is not None:  # session time: since the warm-up ended
            w = spec.warmup_s
            effect.before_record(
                name, t - w, t + dur - w, None if prev_end is None else prev_end - w
            )
        rec = _record(rng, s, name, t, dur, heading, extras.get(name))
        for cut_name, end, missed in spec.turn_cut:
            rec = cut_in_motion(rec, end, missed) if cut_name == name else rec
        s.records.append(rec)
        prev_end = t + dur
        t += dur + rng.uniform(15.0, 25.0)
    return s


def write_session(directory: str | Path, spec: SessionSpec) -> SimSession:
    """Simulate and write ``directory/SERIAL_name.txt`` for every record and
    ``directory/truth.json``; returns the session."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    s = simulate(spec)
    for r in s.records:
        text = record_text(r.name, r.meta, r.t_ms, r.accel, r.gyro, r.temp_c)
        write_record_file(d, spec.serial, r.name, text)
    (d / "truth.json").write_text(json.dumps(s.truth(), indent=1) + "\n", encoding="utf-8")
    return s
