"""A small simulator of archived calibrations, written for the archive's tests apart from the
bench simulator: each unit has a true value per parameter (spread over the lot), each session
measures it with Gaussian noise of the σ the session reports. Planted problems are added on
top: a drifting unit, a biased bench, a unit failing its self-test.

Each session's self-test outcome takes a real session's path: a SELF_TEST_RESULT frame,
decoded by the host, judged by :func:`host.wire.selftest.judge`, written as record header lines
(:meth:`~host.wire.selftest.SelfTest.meta`) and read back as the archive reads them
(:func:`host.archive.entry.self_test_outcome`). The healthy parts' frames come from this
simulator (each part's response within a few % of its factory trim, window noise); the failing
unit's from the virtual board whose chip fails its self-test (``sim://…&self_test=fail``)."""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from host.archive.entry import (
    Entry,
    Parameter,
    archived_verdict,
    diagonal_covariance,
    self_test_outcome,
)
from host.wire.frames import encode_frame
from host.wire.selftest import AXES, accel_factory_trim, gyro_factory_trim, judge, trim_codes
from host.wire.stream import StreamDecoder

#: name -> (unit, lot spread of the true value, σ of one session's fit, nominal)
PARAMETERS: dict[str, tuple[str, float, float, float]] = {
    "A0x": ("m/s²", 0.05, 0.002, 0.0),
    "A0y": ("m/s²", 0.05, 0.002, 0.0),
    "A0z": ("m/s²", 0.08, 0.003, 0.0),
    "Axx": ("", 0.005, 0.0003, 0.0),
    "Ayy": ("", 0.005, 0.0003, 0.0),
    "Azz": ("", 0.005, 0.0003, 0.0),
    "G0x": ("°/s", 1.0, 0.005, 0.0),
    "G0y": ("°/s", 1.0, 0.005, 0.0),
    "G0z": ("°/s", 1.0, 0.005, 0.0),
    "Gxx": ("", 0.005, 0.0005, 0.0),
    "Gyy": ("", 0.005, 0.0005, 0.0),
    "Gzz": ("", 0.005, 0.0005, 0.0),
}
NAMES = tuple(PARAMETERS)
SPREAD = np.array([v[1] for v in PARAMETERS.values()])
SIGMA = np.array([v[2] for v in PARAMETERS.values()])


#: SELF_TEST_X/Y/Z/A of the simulated parts (trim codes XA 22, YA 5, ZA 31, XG 7, YG 1, ZG 30)
SELF_TEST_REGISTERS = (0b101_00111, 0b001_00001, 0b111_11110, 0b00_10_01_11)
#: part-to-part spread of a healthy part's self-test response around its trim (fraction)
SELF_TEST_SPREAD = 0.03


def self_test_fields(rng: np.random.Generator, deviation: np.ndarray) -> dict[str, int]:
    """A SELF_TEST_RESULT of a part whose response is each axis' factory trim × (1 +
    ``deviation``) (ax ay az gx gy gz), the unit lying z up (1 g at ±8 g), each window the mean
    of 32 samples with white noise (accelerometer 4 mg, gyroscope 0.05 °/s per sample)."""
    accel, gyro = trim_codes(*SELF_TEST_REGISTERS)
    trim = np.array([accel_factory_trim(c) for c in accel]
                    + [gyro_factory_trim(c, i) for i, c in enumerate(gyro)])  # fmt: skip
    rest = np.array([0.0, 0.0, 4096.0, 0.0, 0.0, 0.0]) + rng.normal(0.0, [40] * 3 + [60] * 3)
    noise = np.array([0.004 * 4096] * 3 + [0.05 * 131] * 3) / np.sqrt(32)
    windows = {
        "off": rest + rng.normal(0.0, noise),
        "on": rest + trim * (1.0 + deviation) + rng.normal(0.0, noise),
        "end": rest + rng.normal(0.0, noise),
    }
    f = dict(status=0, samples=32)
    f.update(zip(("self_test_x", "self_test_y", "self_test_z", "self_test_a"),
                 SELF_TEST_REGISTERS, strict=True))  # fmt: skip
    for w, v in windows.items():
        f.update({f"{a}_{w}": int(np.rint(x)) for a, x in zip(AXES, v, strict=True)})
    return f


def decoded_self_test(fields: Mapping[str, int], seq: int = 0) -> dict[str, str]:
    """The record header lines of a session whose board sent this SELF_TEST_RESULT: the frame
    on the wire, the host's decoder, the judge."""
    (frame,) = StreamDecoder().feed(encode_frame("SELF_TEST_RESULT", seq, **fields))
    return judge(frame.fields).meta()


@functools.cache
def virtual_board_self_tests(part: str, n: int) -> tuple[dict[str, str], ...]:
    """The record header lines of ``n`` self-tests on the virtual board whose chip answers as
    ``part`` ('pass' or 'fail'): its firmware's frames, the host's :meth:`Board.self_test
    <host.board.driver.Board.self_test>`."""
    from host.board.driver import Board

    board = Board(f"sim://?speed=max&self_test={part}")
    board.connect()
    try:
        return tuple(board.self_test().meta() for _ in range(n))
    finally:
        board.close()


def _hash(*parts: object) -> str:
    return hashlib.sha256(repr(parts).encode()).hexdigest()


def make_entry(
    serial: str,
    bench: str,
    session: int,
    values: np.ndarray,
    sigmas: np.ndarray,
    *,
    day: int = 0,
    self_test: str = "",
    lot: str = "L1",
    tag: str = "",
    header: Mapping[str, str] | None = None,
) -> Entry:
    """One archived calibration of ``serial`` on ``bench`` with these values and σ (in the
    order of :data:`NAMES`); ``day`` orders the sessions in time. The self-test outcome is
    read from the records' ``header`` lines when given, else it is ``self_test``."""
    if header is not None:
        self_test = self_test_outcome([header], serial)
    params = tuple(
        Parameter(n, "bias" if "0" in n else "scale", "accel" if n[0] == "A" else "gyro",
                  n[-1], PARAMETERS[n][0], float(v), float(s))
        for n, v, s in zip(NAMES, values, sigmas, strict=True)
    )  # fmt: skip
    minute = session * 60 + int(_hash(serial)[:4], 16) % 50
    return Entry(
        serial=serial,
        measured_at=f"2026-{1 + day // 28:02d}-{1 + day % 28:02d}T{8 + minute // 60 % 10:02d}:"
        f"{minute % 60:02d}:00.000000Z",
        model="base",
        parameters=params,
        result_hash=_hash("result", serial, bench, session, tag, values.tobytes()),
        bench=bench,
        lot=lot,
        covariance=diagonal_covariance(sigmas),
        verdict=archived_verdict(True, self_test),
        self_test=self_test,
        records_hash=_hash("records", serial, bench, session, tag),
        report_hash=_hash("report", serial, bench, session, tag),
        record_hashes=(("x_up", _hash("x_up", serial, session, tag)),),
        result_json="{}",
    )


@dataclass
class Lot:
    """A simulated lot: the entries and what was planted."""

    entries: list[Entry]
    drifting: str = ""
    biased_bench: str = ""
    failing: str = ""
    reference: str = "REF"
    benches: tuple[str, ...] = ()
    truth: Mapping[str, np.ndarray] = field(default_factory=dict)


def simulate_lot(
    rng: np.random.Generator,
    units: int = 200,
    benches: int = 4,
    sessions: int = 3,
    *,
    plant: bool = True,
    reference_sessions: int = 3,
    lot_name: str = "L1",
    prefix: str = "",
) -> Lot:
    """``units`` units, unit i calibrated ``sessions`` times on bench i mod ``benches``, and a
    reference unit 'REF' calibrated ``reference_sessions`` times on every bench. With
    ``plant``: unit U0007's last session has A0x moved by 40 σ (drift), bench B3 reads G0z
    8 σ high (bias; every unit on it too), unit U0011 fails its self-test."""
    names = tuple(f"B{b + 1}" for b in range(benches))
    bias = {n: np.zeros(len(NAMES)) for n in names}
    lot = Lot([], benches=names, reference=f"{prefix}REF")
    if plant:
        lot.drifting, lot.biased_bench, lot.failing = f"{prefix}U0007", "B3", f"{prefix}U0011"
        bias["B3"][NAMES.index("G0z")] = 8 * SIGMA[NAMES.index("G0z")]
    for i in range(units):
        serial = f"{prefix}U{i:04d}"
        bench = names[i % benches]
        truth = rng.normal(0.0, SPREAD)
        lot.truth[serial] = truth
        part = rng.normal(0.0, SELF_TEST_SPREAD, len(AXES))
        failing = virtual_board_self_tests("fail", sessions) if serial == lot.failing else ()
        for s in range(sessions):
            v = truth + bias[bench] + rng.normal(0.0, SIGMA)
            if serial == lot.drifting and s == sessions - 1:
                v[NAMES.index("A0x")] += 40 * SIGMA[NAMES.index("A0x")]
            header = failing[s] if failing else decoded_self_test(self_test_fields(rng, part), s)
            lot.entries.append(
                make_entry(serial, bench, s, v, SIGMA, day=7 * s, header=header, lot=lot_name)
            )
    truth = rng.normal(0.0, SPREAD)
    lot.truth[lot.reference] = truth
    part = rng.normal(0.0, SELF_TEST_SPREAD, len(AXES))
    for b, bench in enumerate(names):
        for s in range(reference_sessions):
            v = truth + bias[bench] + rng.normal(0.0, SIGMA)
            header = decoded_self_test(self_test_fields(rng, part), s)
            lot.entries.append(
                make_entry(
                    lot.reference, bench, s, v, SIGMA, day=b * 3 + s, header=header, lot=lot_name
                )  # fmt: skip
            )
    return lot
