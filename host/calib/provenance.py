"""Where a result's records came from, read from their headers: the board (simulated or a
unit), the equipment (firmware, sensor, ranges, rate, filter, bus clock), the chip
temperatures, the plan and its timing, who measured and when, and in how many sittings.

A result carries this as data (:class:`Provenance`, the ``provenance`` of a result file v3), so
the report (method.md §7–§8: object, equipment, environment, procedure) and every export can
say it, and a recomputation from the same records (``calibrate --from-dir``) says the same:
nothing here is the time or place of the computation except ``software`` and ``computed_at``.
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from host.session.directory import (
    EARLIER_DIR,
    SIMULATED_BOARD,
    SIMULATED_SCHEMES,
    Session,
    measured_order,
    sittings_in_order,
    split_file_name,
)
from host.session.records import NON_RECORD_NAMES, STOPPED_KEY, TARGET_KEY, Record

#: header keys of the equipment (record header -> words of the report), in report order
EQUIPMENT_KEYS = {
    "firmware": "firmware version",
    "protocol_version": "protocol version",
    "who_am_i": "WHO_AM_I",
    "product_id": "product ID",
    "sensor_revision": "sensor revision",
    "accel_range_g": "accelerometer range, ±g",
    "gyro_range_dps": "gyro range, ±°/s",
    "sample_rate_hz": "sample rate, Hz",
    "smplrt_div": "sample rate divider",
    "dlpf_cfg": "digital low-pass filter (DLPF_CFG)",
    "sensor_spi_clock": "SPI clock",
}

#: the MPU-6000's WHO_AM_I register value
MPU6000_WHO_AM_I = "0x68"

UNKNOWN_SENSOR = "unknown sensor"


@dataclass(frozen=True)
class Sitting:
    """One sitting at the bench (a live run; ``--resume`` and ``--redo`` start another): its
    capture file (``''``: records that came without one) and its records in measured order."""

    capture: str
    records: tuple[str, ...]


@dataclass(frozen=True)
class SetAside:
    """Records of the unit kept aside, not in the result: ``folder``, under the records'
    directory (``earlier/SERIAL_<UTC time>``), and the records in it — a record measured
    again (``--redo``, a record repeated) or an earlier sitting's, moved when a new sitting
    began (:func:`host.session.directory.set_aside`)."""

    folder: str
    records: tuple[str, ...]


@dataclass(frozen=True)
class Provenance:
    """What the records say about how they were measured; text as the headers wrote it.

    ``simulated``: the records came from a virtual or emulated board or from the simulator,
    ``simulated_by`` which (port URLs, or ``source: sim`` records). ``sensor``: the chip named
    from the data (``MPU-6000 rev D8``) or :data:`UNKNOWN_SENSOR`. ``equipment``: header key ->
    value (several values joined by ' / '). ``temp_c``: chip temperature low, high, °C (None:
    not measured). ``static_s``/``turn_s``: shortest and longest record of each kind, s;
    ``turn_window_s``: the turn windows the plan gave, s. ``measured_from``/``measured_to``:
    the first and last record's start time (ISO, from the headers; '' when they have none).
    ``measured_order``: every record, in the order measured. ``software``: this program and
    its version at the computation. ``stopped``: record -> why it stopped (its header's
    ``stopped``: records that stop when they have enough, ``calibrate --plan adaptive``).
    """

    simulated: bool = False
    simulated_by: tuple[str, ...] = ()
    sensor: str = UNKNOWN_SENSOR
    equipment: Mapping[str, str] = field(default_factory=dict)
    ports: tuple[str, ...] = ()
    sources: tuple[str, ...] = ()
    programs: tuple[str, ...] = ()
    operators: tuple[str, ...] = ()
    benches: tuple[str, ...] = ()
    temp_c: tuple[float, float] | None = None
    static_s: tuple[float, float] | None = None
    turn_s: tuple[float, float] | None = None
    turn_window_s: tuple[float, ...] = ()
    turns: tuple[int, ...] = ()
    measured_from: str = ""
    measured_to: str = ""
    measured_order: tuple[str, ...] = ()
    #: record -> its start in seconds since its sitting began (``session_s``; absent: unknown)
    session_s: Mapping[str, float] = field(default_factory=dict)
    sittings: tuple[Sitting, ...] = ()
    software: str = ""
    stopped: Mapping[str, str] = field(default_factory=dict)
    #: records of the unit kept aside in ``earlier/``, oldest folder first (not in the result)
    set_aside: tuple[SetAside, ...] = ()
    #: record -> SHA-256 (hex) of its file as fitted (absent: records that were not files)
    record_sha256: Mapping[str, str] = field(default_factory=dict)
    #: the worst σ/tolerance the adaptive plan measured towards (the records'
    #: ``plan_target``; None: no adaptive plan)
    target: float | None = None

    @property
    def simulated_line(self) -> str:
        """``SIMULATED BOARD <by>: not a measurement of a unit``, or '' for a unit."""
        if not self.simulated:
            return ""
        return f"{SIMULATED_BOARD} {', '.join(self.simulated_by)}: not a measurement of a unit"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (a result file's ``provenance``)."""
        return {
            "simulated": self.simulated,
            "simulated_by": list(self.simulated_by),
            "sensor": self.sensor,
            "equipment": dict(self.equipment),
            "ports": list(self.ports),
            "sources": list(self.sources),
            "programs": list(self.programs),
            "operators": list(self.operators),
            "benches": list(self.benches),
            "temp_c": None if self.temp_c is None else list(self.temp_c),
            "static_s": None if self.static_s is None else list(self.static_s),
            "turn_s": None if self.turn_s is None else list(self.turn_s),
            "turn_window_s": list(self.turn_window_s),
            "turns": list(self.turns),
            "measured_from": self.measured_from,
            "measured_to": self.measured_to,
            "measured_order": list(self.measured_order),
            "session_s": dict(self.session_s),
            "sittings": [{"capture": s.capture, "records": list(s.records)} for s in self.sittings],
            "software": self.software,
            "stopped": dict(self.stopped),
            "set_aside": [{"folder": s.folder, "records": list(s.records)} for s in self.set_aside],
            "record_sha256": dict(self.record_sha256),
        } | ({} if self.target is None else {"target": self.target})

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Provenance:
        """Inverse of :meth:`to_dict` (missing keys: their defaults)."""

        def pair(key: str) -> tuple[float, float] | None:
            v = d.get(key)
            return None if v is None else (float(v[0]), float(v[1]))

        def strs(key: str) -> tuple[str, ...]:
            return tuple(str(x) for x in d.get(key, ()))

        return cls(
            simulated=bool(d.get("simulated", False)),
            simulated_by=strs("simulated_by"),
            sensor=str(d.get("sensor", UNKNOWN_SENSOR)),
            equipment={str(k): str(v) for k, v in d.get("equipment", {}).items()},
            ports=strs("ports"),
            sources=strs("sources"),
            programs=strs("programs"),
            operators=strs("operators"),
            benches=strs("benches"),
            temp_c=pair("temp_c"),
            static_s=pair("static_s"),
            turn_s=pair("turn_s"),
            turn_window_s=tuple(float(x) for x in d.get("turn_window_s", ())),
            turns=tuple(int(x) for x in d.get("turns", ())),
            measured_from=str(d.get("measured_from", "")),
            measured_to=str(d.get("measured_to", "")),
            measured_order=strs("measured_order"),
            session_s={str(k): float(v) for k, v in d.get("session_s", {}).items()},
            sittings=tuple(
                Sitting(str(s["capture"]), tuple(str(x) for x in s["records"]))
                for s in d.get("sittings", ())
            ),
            software=str(d.get("software", "")),
            stopped={str(k): str(v) for k, v in d.get("stopped", {}).items()},
            set_aside=tuple(
                SetAside(str(s["folder"]), tuple(str(x) for x in s["records"]))
                for s in d.get("set_aside", ())
            ),
            record_sha256={str(k): str(v) for k, v in d.get("record_sha256", {}).items()},
            target=None if d.get("target") is None else float(d["target"]),
        )


def _distinct(records: Mapping[str, Record], key: str) -> tuple[str, ...]:
    """The distinct non-empty values of header ``key``, in first-seen order."""
    seen: dict[str, None] = {}
    for r in records.values():
        v = r.meta.get(key, "").strip()
        if v:
            seen.setdefault(v, None)
    return tuple(seen)


def simulated_sources(records: Mapping[str, Record]) -> tuple[str, ...]:
    """What simulated the records: the ``sim://``/``emu://`` port URLs, and
    ``simulator (source: sim)`` for records the simulator wrote without a port (``demo``)."""
    out = [p for p in _distinct(records, "port") if p.startswith(SIMULATED_SCHEMES)]
    if any(
        r.meta.get("source", "").strip() == "sim" and not r.meta.get("port")
        for r in records.values()
    ):
        out.append("simulator (source: sim)")
    return tuple(out)


def sensor_name(records: Mapping[str, Record]) -> str:
    """The chip the records name: ``MPU-6000 rev D8`` from WHO_AM_I 0x68 and the revision,
    else :data:`UNKNOWN_SENSOR` (imported data, e.g. imucal's 16-bit unit, names none)."""
    who = _distinct(records, "who_am_i")
    if not who or any(w.lower() != MPU6000_WHO_AM_I for w in who):
        return UNKNOWN_SENSOR
    rev = _distinct(records, "sensor_revision")
    return "MPU-6000" + (f" rev {' / '.join(rev)}" if rev else "")


def _span(values: list[float]) -> tuple[float, float] | None:
    return (min(values), max(values)) if values else None


def _order_key(r: Record, sitting: int) -> tuple[int, float, str]:
    try:
        s = float(r.meta.get("session_s", "nan"))
    except ValueError:
        s = math.nan
    return (sitting, s if math.isfinite(s) else math.inf, r.meta.get("start_time", ""))


def provenance_of(session: Session, software: str = "") -> Provenance:
    """The :class:`Provenance` of a session, from its records' headers and samples;
    ``software``: this program and version (the computation's, not the records')."""
    recs = session.records
    captures = sittings_in_order(recs)
    sit_of = {n: captures.index(r.meta["capture"].strip()) if r.meta.get("capture", "").strip()
              else len(captures) for n, r in recs.items()}  # fmt: skip
    order = tuple(measured_order(recs))
    sittings = tuple(
        Sitting(cap, tuple(n for n in order if sit_of[n] == i))
        for i, cap in enumerate((*captures, ""))
        if any(sit_of[n] == i for n in order)
    )
    temps = [r.temp[np.isfinite(r.temp)] for r in recs.values() if _temp_measured(r)]
    temp_all = np.concatenate(temps) if temps else np.zeros(0)
    statics = [r.duration_s for r in recs.values() if r.kind == "static"]
    turns = [r.duration_s for r in recs.values() if r.kind == "turn"]
    starts = sorted(_distinct(recs, "start_time"))
    sims = simulated_sources(recs)
    equipment = {
        k: " / ".join(v) for k in EQUIPMENT_KEYS if (v := _distinct(recs, k))
    }  # fmt: skip
    windows = sorted({float(w) for w in _distinct(recs, "window_s") if _is_number(w)})
    n_turns = sorted({int(t) for t in _distinct(recs, "turns") if t.isdigit()})
    return Provenance(
        simulated=bool(sims),
        simulated_by=sims,
        sensor=sensor_name(recs),
        equipment=equipment,
        ports=_distinct(recs, "port"),
        sources=_distinct(recs, "source"),
        programs=_distinct(recs, "program"),
        operators=_distinct(recs, "operator"),
        benches=_distinct(recs, "bench"),
        temp_c=(float(temp_all.min()), float(temp_all.max())) if temp_all.size else None,
        static_s=_span(statics),
        turn_s=_span(turns),
        turn_window_s=tuple(windows),
        turns=tuple(n_turns),
        measured_from=starts[0] if starts else "",
        measured_to=starts[-1] if starts else "",
        measured_order=order,
        session_s={n: at for n in order if math.isfinite(at := _order_key(recs[n], 0)[1])},
        sittings=sittings,
        software=software,
        stopped={n: w for n in order if (w := recs[n].meta.get(STOPPED_KEY, "").strip())},
        set_aside=() if session.directory is None else set_aside_records(session.directory,
                                                                          session.serial),
        record_sha256=record_digests(session),
        target=plan_target(recs),
    )  # fmt: skip


def plan_target(records: Mapping[str, Record]) -> float | None:
    """The target of the adaptive plan the records were measured under (their
    ``plan_target``, the last record's that has one; None: none has)."""
    for r in reversed(list(records.values())):
        try:
            t = float(r.meta.get(TARGET_KEY, "nan"))
        except ValueError:
            continue
        if math.isfinite(t) and t > 0:
            return t
    return None


def record_digests(session: Session) -> dict[str, str]:
    """Each record's file in the session's directory -> its SHA-256 (hex): what proves later
    which files a result was fitted on (``archive add --records`` checks them). Records that
    are not files there (a session made in memory) have none."""
    if session.directory is None:
        return {}
    out = {}
    for name in sorted(session.records):
        path = Path(session.directory) / session.path_of(name)
        if path.is_file():
            out[name] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def set_aside_records(directory: str | os.PathLike[str], serial: str) -> tuple[SetAside, ...]:
    """The records of ``serial`` kept aside under ``directory/earlier/``, one
    :class:`SetAside` per folder, oldest first (the folders are named by UTC time)."""
    root = Path(directory) / EARLIER_DIR
    if not root.is_dir():
        return ()
    out = []
    for sub in sorted(p for p in root.iterdir() if p.name.startswith(f"{serial}_")):
        if not sub.is_dir():
            continue
        names = [
            parts[1] for p in sorted(sub.iterdir())
            if (parts := split_file_name(p)) is not None and parts[0] == serial
            and parts[1] not in NON_RECORD_NAMES and p.is_file()
        ]  # fmt: skip
        if names:
            out.append(SetAside(f"{EARLIER_DIR}/{sub.name}", tuple(names)))
    return tuple(out)


def _temp_measured(r: Record) -> bool:
    """False for records whose temperature column is a filler (``import`` of data without
    one says ``temperature: not recorded``; older imports said it in ``source``)."""
    said = (r.meta.get("temperature", "") + " " + r.meta.get("source", "")).lower()
    return len(r.temp) > 0 and "not recorded" not in said and "temperature not measured" not in said


def _is_number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False
