"""A small simulator of archived calibrations, written for the archive's tests apart from the
bench simulator: each unit has a true value per parameter (spread over the lot), each session
measures it with Gaussian noise of the σ the session reports. Planted problems are added on
top: a drifting unit, a biased bench, a unit failing its self-test."""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from host.archive.entry import Entry, Parameter, diagonal_covariance

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
) -> Entry:
    """One archived calibration of ``serial`` on ``bench`` with these values and σ (in the
    order of :data:`NAMES`); ``day`` orders the sessions in time."""
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
        verdict="fail" if self_test == "fail" else "pass",
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
) -> Lot:
    """``units`` units, unit i calibrated ``sessions`` times on bench i mod ``benches``, and a
    reference unit 'REF' calibrated ``reference_sessions`` times on every bench. With
    ``plant``: unit U0007's last session has A0x moved by 40 σ (drift), bench B3 reads G0z
    8 σ high (bias; every unit on it too), unit U0011 fails its self-test."""
    names = tuple(f"B{b + 1}" for b in range(benches))
    bias = {n: np.zeros(len(NAMES)) for n in names}
    lot = Lot([], benches=names)
    if plant:
        lot.drifting, lot.biased_bench, lot.failing = "U0007", "B3", "U0011"
        bias["B3"][NAMES.index("G0z")] = 8 * SIGMA[NAMES.index("G0z")]
    for i in range(units):
        serial = f"U{i:04d}"
        bench = names[i % benches]
        truth = rng.normal(0.0, SPREAD)
        lot.truth[serial] = truth
        for s in range(sessions):
            v = truth + bias[bench] + rng.normal(0.0, SIGMA)
            if serial == lot.drifting and s == sessions - 1:
                v[NAMES.index("A0x")] += 40 * SIGMA[NAMES.index("A0x")]
            st = "fail" if serial == lot.failing else "pass"
            lot.entries.append(make_entry(serial, bench, s, v, SIGMA, day=7 * s, self_test=st))
    truth = rng.normal(0.0, SPREAD)
    lot.truth[lot.reference] = truth
    for b, bench in enumerate(names):
        for s in range(reference_sessions):
            v = truth + bias[bench] + rng.normal(0.0, SIGMA)
            lot.entries.append(
                make_entry(lot.reference, bench, s, v, SIGMA, day=b * 3 + s, self_test="pass")
            )
    return lot
