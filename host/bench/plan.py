"""Simulated sessions: a plan of records, measured on the virtual bench and written as files.

:class:`Plan` lists what a session measures (statics, turns, tilted attitudes, rate-table
records; :class:`RecordSpec` each); :func:`simulate_session` runs it on a
:class:`host.bench.sim.Simulator` and returns the records exactly as the calibration program
records them (a fast path for tests), :func:`write_session` writes them as record files, and
:func:`simulate_thermal` gives static records while the chip's temperature moves.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from host.bench.physics import (
    Bench,
    Environment,
    Motion,
    static_motion,
    up_vector,
)
from host.bench.sim import Simulator, rate_table_motion, turn_motion
from host.bench.truth import SensorTruth
from host.session.directory import record_path, write_record
from host.session.records import HEADING_KEY, STATIC_NAMES, Record, turn_window_s


def tilted_45() -> tuple[tuple[str, tuple[float, float, float]], ...]:
    """The 12 attitudes with an edge of the cube up (two axes at 45° to the vertical):
    names ``tilt_45_1`` … ``tilt_45_12`` and body up vectors."""
    out = []
    h = float(np.sqrt(0.5))
    k = 0
    for a, b in ((0, 1), (0, 2), (1, 2)):
        for sa in (1, -1):
            for sb in (1, -1):
                v = [0.0, 0.0, 0.0]
                v[a], v[b] = sa * h, sb * h
                k += 1
                out.append((f"tilt_45_{k}", (v[0], v[1], v[2])))
    return tuple(out)


@dataclass(frozen=True)
class RecordSpec:
    """One record of a plan: what the cube does between the two beeps."""

    name: str
    kind: str  # "static" | "turn" | "rate"
    duration_s: float
    up: tuple[float, float, float]
    turns: int = 0
    direction: int = 0  # +1 ccw, -1 cw
    rate_dps: float = 0.0


@dataclass(frozen=True)
class Plan:
    """What a simulated session measures.

    Static records of ``static_s`` s for ``statics``; for each of ``turn_axes`` a ccw and a cw
    record of ``turns`` turns in the fixed window (7/12/15 s); optional ``tilted`` static
    attitudes (name, body up vector; see :func:`tilted_45`) and ``rate_table`` records
    (axis, rate °/s) of ``rate_table_s`` s. The first record starts after ``warmup_s`` s of
    power; ``gap_s`` s of handling between records. ``environment`` None: drawn from the seed.
    """

    static_s: float = 30.0
    turns: int = 2
    statics: tuple[str, ...] = STATIC_NAMES
    turn_axes: tuple[str, ...] = ("x", "y", "z")
    tilted: tuple[tuple[str, tuple[float, float, float]], ...] = ()
    rate_table: tuple[tuple[str, float], ...] = ()
    rate_table_s: float = 10.0
    warmup_s: float = 600.0
    gap_s: float = 20.0
    window_s: float | None = None
    bench: Bench = field(default_factory=Bench)
    environment: Environment | None = None
    rate_hz: float = 50.0

    def specs(self) -> list[RecordSpec]:
        """The records in measuring order."""
        out = []
        for name in self.statics:
            out.append(RecordSpec(name, "static", self.static_s, _t3(up_vector(name))))
        for name, up in self.tilted:
            out.append(RecordSpec(name, "static", self.static_s, _t3(np.asarray(up))))
        window = self.window_s or turn_window_s(self.turns)
        for axis in self.turn_axes:
            for d, sfx in ((1, "ccw"), (-1, "cw")):
                up = _t3(up_vector(f"{axis}_up"))
                out.append(RecordSpec(f"{axis}_{sfx}", "turn", window, up, self.turns, d))
        for axis, rate in self.rate_table:
            name = f"rate_{axis}_{'p' if rate >= 0 else 'm'}{abs(rate):g}"
            up = _t3(up_vector(f"{axis}_up"))
            out.append(RecordSpec(name, "rate", self.rate_table_s, up, rate_dps=rate))
        return out


def _t3(v: np.ndarray) -> tuple[float, float, float]:
    v = np.asarray(v, dtype=float)
    return (float(v[0]), float(v[1]), float(v[2]))


def format_up(up: np.ndarray | Sequence[float]) -> str:
    """Up vector for record meta: '+x' for an axis, else '[0.7071, 0, 0.7071]'."""
    v = np.asarray(up, dtype=float)
    k = int(np.argmax(np.abs(v)))
    if abs(abs(v[k]) - 1.0) < 1e-12:
        return ("+" if v[k] > 0 else "-") + "xyz"[k]
    return "[" + ", ".join(f"{x:.6g}" for x in v) + "]"


def simulate_session(
    truth: SensorTruth,
    plan: Plan | None = None,
    seed: int = 0,
    hand: np.random.SeedSequence | None = None,
) -> dict[str, Record]:
    """Simulate every record of ``plan`` (default: 6 × 30 s statics + 6 turns of 2) as the
    calibration program would record them: ``t_ms`` ms since the start beep (device clock),
    accel m/s², gyro °/s, temp °C from the counts; meta ``kind``/``up``/``turns``/… .
    ``hand``: the seed of the hand's motions (default: drawn from ``seed``); the boards of one
    cube share it (:func:`host.bench.cube.simulate_sitting`)."""
    plan = plan or Plan()
    env_ss, motion_ss, sensor_ss = np.random.SeedSequence(seed).spawn(3)
    env = plan.environment or Environment.random(np.random.default_rng(env_ss))
    sim = Simulator(truth, plan.bench, env, sensor_ss, plan.rate_hz)
    motion_rng = np.random.default_rng(motion_ss if hand is None else hand)
    records: dict[str, Record] = {}
    t = plan.warmup_s
    for spec in plan.specs():
        up = np.asarray(spec.up)
        meta = {
            "kind": spec.kind,
            "up": format_up(up),
            "source": "sim",
            "sim_seed": str(seed),
            HEADING_KEY: "0",  # pose_from_up: the reference axis along the ruler
            "power_on_s": f"{t:.3f}",
            "session_s": f"{t - plan.warmup_s:.3f}",
        }
        motion, more = _record_motion(spec, up, t, motion_rng, plan.bench)
        meta.update(more)
        sim.skip_until(t)
        sim.set_motion(motion, t)
        block = sim.run_until(t + spec.duration_s)
        beep_us = int(env.device_us(np.array([t]))[0])
        records[spec.name] = Record(
            name=spec.name,
            t_ms=(block.t_us - beep_us) / 1000.0,
            accel=block.accel,
            gyro=block.gyro,
            temp=block.temp,
            meta=meta,
        )
        t += spec.duration_s + plan.gap_s
    return records


def _record_motion(
    spec: RecordSpec, up: np.ndarray, t: float, rng: np.random.Generator, bench: Bench
) -> tuple[Motion, dict[str, str]]:
    """The cube's motion for record ``spec`` from its start beep at ``t`` s (a turn's drawn by
    the hand ``rng``), and the meta it adds to the record's."""
    if spec.kind == "turn":
        turn = turn_motion(
            rng, up, t, spec.duration_s, spec.turns, spec.direction, bench.wobble_deg
        )
        return turn, {
            "turns": str(spec.turns),
            "direction": "ccw" if spec.direction > 0 else "cw",
            "window_s": f"{spec.duration_s:g}",
        }
    if spec.kind == "rate":
        meta = {"rate_dps": f"{spec.rate_dps:g}", "rate_axis": format_up(up)}
        return rate_table_motion(up, spec.rate_dps, t), meta
    return static_motion(up), {}


def write_session(
    out_dir: str | os.PathLike[str], serial: str, records: dict[str, Record]
) -> list[Path]:
    """Write each record to ``out_dir/SERIAL_name.txt`` exactly as the calibration program
    does (:func:`host.session.directory.write_record`); -> the paths written."""
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    paths = []
    for name, rec in records.items():
        p = record_path(out_dir, serial, name)
        meta = {"serial": serial, **rec.meta}
        write_record(p, Record(rec.name, rec.t_ms, rec.accel, rec.gyro, rec.temp, meta))
        paths.append(p)
    return paths


def simulate_thermal(
    truth: SensorTruth,
    environment: Environment,
    segments: Sequence[tuple[str, str, float]],
    seed: int = 0,
    bench: Bench | None = None,
    rate_hz: float = 50.0,
) -> dict[str, Record]:
    """A thermal plan: static records one after another from power-on, each
    ``(name, face, duration_s)`` (e.g. ``("warmup", "z_up", 600)`` then a chamber ramp) — the
    cube at rest on ``face`` while ``environment`` (its warm-up, a chamber ramp) moves the chip
    temperature. Meta: ``kind: static``, ``up``, ``power_on_s``."""
    bench = bench or Bench()
    sim = Simulator(truth, bench, environment, seed, rate_hz)
    out: dict[str, Record] = {}
    t = 0.0
    for name, face, duration in segments:
        up = up_vector(face)
        sim.set_motion(static_motion(face), t)
        block = sim.run_until(t + duration)
        meta = {"kind": "static", "up": format_up(up), "source": "sim", "power_on_s": f"{t:.3f}"}
        t_ms = (block.t_s - block.t_s[0]) * 1000.0
        out[name] = Record(name, t_ms, block.accel, block.gyro, block.temp, meta)
        t += duration
    return out
