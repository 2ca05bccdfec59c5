"""The noise of a static recording, as the ``noise`` command reports it.

:func:`analyse` takes times, the six channels and the chip temperature; it removes a drift that
follows the temperature (:func:`thermal_drift`: a warm-up inside the recording would otherwise
read as rate random walk), then reads each channel's figures with :mod:`host.model.allan`.
:func:`plan` turns the fitted model into recording lengths; the noise file
(:meth:`NoiseAnalysis.as_dict`, :func:`load_noise_file`) carries the figures to the workbench,
whose noise floor of a record mean is :func:`record_mean_floor`.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from host.errors import UserError
from host.model.allan import (
    CHANNELS,
    CI_LEVEL,
    PHASE_BLOCK,
    QUANTITIES,
    UNITS,
    ChannelNoise,
    Figure,
    allan_curve_of_phase,
    basis,
    fit_noise,
    plan_duration,
    relative_precision,
    sensor_of,
)
from host.session.inputs import load_json
from host.session.spacing import ValueCounts
from host.wire.sensor import G0

__all__ = [
    "CHANNELS",
    "CI_LEVEL",
    "QUANTITIES",
    "UNITS",
    "ChannelNoise",
    "Figure",
    "NoiseAnalysis",
    "analyse",
    "basis",
    "load_noise_file",
    "plan",
    "plan_duration",
    "record_mean_floor",
    "workbench_floor",
    "relative_precision",
    "thermal_drift",
]


# --------------------------------------------------------------------------- temperature
@dataclass(frozen=True)
class ThermalDrift:
    """What the chip temperature explains in one channel: ``coefficient`` (unit/°C) of a
    straight line against temperature, ``drift`` = coefficient × span (channel unit), and
    whether it is ``significant`` (larger than the noise allows over the recording)."""

    coefficient: float
    drift: float
    significant: bool


def thermal_drift(
    x: np.ndarray, temp_c: np.ndarray, rate_hz: float, min_span_c: float = 0.5
) -> tuple[float, dict[int, ThermalDrift]]:
    """Temperature span of the recording (°C, 1st–99th percentile) and, when it is at least
    ``min_span_c``, per column of ``x`` (N, k) the straight-line fit against temperature.

    A drift is significant when the change it explains across the span exceeds five times the
    slow wander of what is left (the standard deviation of the residual's means over 16 equal
    blocks): a chance correlation of slow noise with the temperature stays below that."""
    t = np.asarray(temp_c, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64).reshape(t.size, -1)
    if t.size < 16 or not np.all(np.isfinite(t)):
        return 0.0, {}
    temps = ValueCounts()
    temps.add(t)
    span = temps.percentile(99) - temps.percentile(1)
    if span < min_span_c:
        return span, {}
    source = ArrayBlocks(np.zeros(t.size), x, t)
    return span, _drifts(source, x.mean(axis=0), float(t.mean()), span)


def _drifts(source: Blocks, xbar: np.ndarray, tbar: float, span: float) -> dict[int, ThermalDrift]:
    """:func:`thermal_drift`'s lines, one pass over ``source`` (its means known)."""
    n, k = source.size, xbar.size
    per = n // 16
    sdd, sdc = 0.0, np.zeros(k)
    bx, bt = np.zeros((16, k)), np.zeros(16)
    i = 0
    for _, x, tc in source.blocks():
        assert tc is not None
        d = tc - tbar
        sdd += float(d @ d)
        sdc += d @ (x - xbar)
        blk = np.arange(i, i + d.size) // per
        keep = blk < 16
        bt += np.bincount(blk[keep], weights=tc[keep], minlength=16)
        for j in range(k):
            bx[:, j] += np.bincount(blk[keep], weights=x[keep, j], minlength=16)
        i += d.size
    out: dict[int, ThermalDrift] = {}
    for j in range(k):
        c = float(sdc[j] / sdd)
        blocks = (bx[:, j] / per - xbar[j]) - c * (bt / per - tbar)
        limit = 5.0 * float(blocks.std(ddof=1))
        out[j] = ThermalDrift(c, c * span, abs(c * span) > limit)
    return out


# --------------------------------------------------------------------------- in blocks
#: samples per block when a recording held in memory is read in passes
BLOCK = 1 << 18


class Blocks(Protocol):
    """A static recording read in blocks, as many times as asked: ``size`` samples;
    :meth:`blocks` yields (times (b,) s, channels (b, k), temperature (b,) °C or None) in
    order."""

    @property
    def size(self) -> int: ...

    def blocks(self) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray | None]]: ...


@dataclass(frozen=True)
class ArrayBlocks:
    """:class:`Blocks` of arrays held in memory (times s, channels (N, k), temperature °C)."""

    t_s: np.ndarray
    data: np.ndarray
    temp_c: np.ndarray | None
    block: int = BLOCK

    @property
    def size(self) -> int:
        return int(np.shape(self.t_s)[0])

    def blocks(self) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray | None]]:
        for a in range(0, self.size, self.block):
            b = a + self.block
            tc = None if self.temp_c is None else self.temp_c[a:b]
            yield self.t_s[a:b], self.data[a:b], tc


class PhaseStore(Protocol):
    """Where a channel's phase (:func:`host.model.allan.phase_of`) is kept while its Allan
    deviation is worked out: appended in pieces, read back by windows."""

    def append(self, values: np.ndarray) -> None: ...

    def window(self, a: int, b: int) -> np.ndarray: ...


class MemoryPhases:
    """A :class:`PhaseStore` in memory."""

    def __init__(self) -> None:
        self._parts: list[np.ndarray] = []

    def append(self, values: np.ndarray) -> None:
        self._parts.append(np.asarray(values, dtype=np.float64))

    def window(self, a: int, b: int) -> np.ndarray:
        if len(self._parts) != 1:
            self._parts = [np.concatenate(self._parts)]
        return self._parts[0][a:b]


# --------------------------------------------------------------------------- the analysis
@dataclass(frozen=True)
class NoiseAnalysis:
    """Everything :func:`analyse` found: per channel :class:`ChannelNoise`, the recording's
    ``duration_s``, ``rate_hz``, temperature ``span_c`` and per channel the thermal drift
    (removed before the Allan deviation when significant and ``thermal_removed``)."""

    channels: dict[str, ChannelNoise]
    duration_s: float
    rate_hz: float
    span_c: float
    thermal: dict[str, ThermalDrift] = field(default_factory=dict)
    thermal_removed: bool = True
    ci: float = CI_LEVEL
    warnings: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        """The ``--json`` document (also the noise file the workbench reads)."""
        chans: dict[str, Any] = {}
        for name, ch in self.channels.items():
            chans[name] = {q: ch.figures[q].as_dict() for q in QUANTITIES}
        thermal = {
            name: {
                "coefficient": d.coefficient,
                "unit": UNITS[sensor_of(name)][1] + "/degC",
                "drift": d.drift,
                "significant": d.significant,
                "removed": d.significant and self.thermal_removed,
            }
            for name, d in self.thermal.items()
        }
        return {
            "format": "imu-bench noise",
            "format_version": NOISE_FORMAT_VERSION,
            "duration_s": self.duration_s,
            "rate_hz": self.rate_hz,
            "ci_level": self.ci,
            "model": "sigma^2(tau) = N^2/tau + (2 ln2/pi) B^2 + K^2 tau/3",
            "channels": chans,
            "temperature": {"span_c": self.span_c, "channels": thermal},
            "warnings": list(self.warnings),
        }


NOISE_FORMAT_VERSION = 1


def analyse(
    t_s: np.ndarray,
    data: np.ndarray,
    temp_c: np.ndarray | None = None,
    channels: Sequence[str] = CHANNELS,
    remove_thermal: bool = True,
    ci: float = CI_LEVEL,
) -> NoiseAnalysis:
    """The noise of a static recording: sample times ``t_s`` (N,) s, ``data`` (N, k) in the
    channels' units (m/s², °/s), ``temp_c`` (N,) °C or None (:func:`analyse_blocks`)."""
    t = np.asarray(t_s, dtype=np.float64)
    x = np.asarray(data, dtype=np.float64).reshape(t.size, len(channels))
    tc = None if temp_c is None else np.asarray(temp_c, dtype=np.float64)
    source = ArrayBlocks(t, x, tc, block=max(t.size, 1))
    return analyse_blocks(source, channels, remove_thermal, ci, phase_block=t.size + 1)


def analyse_blocks(
    source: Blocks,
    channels: Sequence[str] = CHANNELS,
    remove_thermal: bool = True,
    ci: float = CI_LEVEL,
    phases: Callable[[], PhaseStore] = MemoryPhases,
    phase_block: int = PHASE_BLOCK,
) -> NoiseAnalysis:
    """:func:`analyse` of a recording read in blocks, in three passes (spacing and means; the
    temperature lines; the phases, kept in a store from ``phases``): memory bounded by the
    blocks and the stores, whatever the length.

    The rate is the median sample spacing; gaps are reported as a warning (the Allan
    deviation assumes even sampling) and the duration is the samples', without the gaps. A
    significant temperature drift is removed first when ``remove_thermal`` (see
    :func:`thermal_drift`)."""
    k = len(channels)
    first = _first_pass(source, k)
    n = first.n
    if n < 64:
        raise ValueError(f"{n} samples: an Allan deviation needs at least 64")
    step = first.spacing.median()
    if not step > 0:
        raise ValueError("the sample times do not increase")
    rate = 1.0 / step
    notes = _gap_notes(first, step)
    xbar, tbar = first.sx / n, first.st / n
    span, drifts = 0.0, {}
    if first.temp_ok and n >= 16:
        span = first.temps.percentile(99) - first.temps.percentile(1)
        if span >= 0.5:
            drifts = _drifts(source, xbar, tbar, span)
    coef, note = _thermal_removal(drifts, channels, span, remove_thermal)
    notes += note
    stores = _phases_of(source, coef, xbar, tbar, rate, phases, k)
    out: dict[str, ChannelNoise] = {}
    for j, name in enumerate(channels):
        curve = allan_curve_of_phase(stores[j].window, n, rate, block=phase_block)
        stores[j] = MemoryPhases()  # let it go
        out[name] = fit_noise(name, curve, ci)
    for name, ch in out.items():
        for q in QUANTITIES:
            w = ch.figures[q].warning
            if w:
                notes.append(f"{name}: {w}")
    # the samples' length, not the span of their times: a gap holds no samples
    duration = float(n) * step
    thermal = {channels[j]: d for j, d in drifts.items()}
    return NoiseAnalysis(out, duration, rate, span, thermal, remove_thermal, ci, tuple(notes))


@dataclass
class _FirstPass:
    """What the first pass over a recording's blocks gathers: the samples' count, first and
    last time, the spacings and chip temperatures (as counts of values), the channels' sums
    and the temperatures' sum (``temp_ok``: every sample has a finite temperature)."""

    n: int
    t_first: float
    t_last: float
    spacing: ValueCounts
    temps: ValueCounts
    sx: np.ndarray
    st: float
    temp_ok: bool


def _first_pass(source: Blocks, k: int) -> _FirstPass:
    f = _FirstPass(0, 0.0, 0.0, ValueCounts(), ValueCounts(), np.zeros(k), 0.0, True)
    for t, x, tc in source.blocks():
        if t.size == 0:
            continue
        f.spacing.add(np.diff(t) if f.n == 0 else np.diff(np.concatenate([[f.t_last], t])))
        f.t_first, f.t_last = (float(t[0]) if f.n == 0 else f.t_first), float(t[-1])
        f.n += t.size
        f.sx += x.sum(axis=0)
        if tc is None or not np.all(np.isfinite(tc)):
            f.temp_ok = False
        else:
            f.temps.add(tc)
            f.st += float(tc.sum())
    return f


def _gap_notes(first: _FirstPass, step: float) -> list[str]:
    """The warning for gaps in the sample times (spacings over 1.5 steps) that hold more than
    0.1 % of the recording."""
    spacing = first.spacing
    gaps = spacing.values > 1.5 * step
    if not np.any(gaps):
        return []
    lost = float(np.sum((spacing.values[gaps] - step) * spacing.counts[gaps]))
    share = lost / (first.t_last - first.t_first)
    if share <= 0.001:
        return []
    return [
        f"{int(spacing.counts[gaps].sum())} gaps in the sample times "
        f"({100 * share:.1f} % of the recording): the Allan deviation treats the "
        "samples as evenly spaced"
    ]


def _thermal_removal(
    drifts: Mapping[int, ThermalDrift], channels: Sequence[str], span: float, remove: bool
) -> tuple[np.ndarray, list[str]]:
    """Each channel's temperature coefficient to remove (0 where not significant, or when
    not ``remove``), and the note saying which channels follow the temperature."""
    coef = np.zeros(len(channels))
    sig = [channels[j] for j, d in drifts.items() if d.significant]
    if not sig:
        return coef, []
    what = "removed before the Allan deviation" if remove else "NOT removed"
    note = (
        f"temperature drift: the chip moved {span:.1f} °C and {', '.join(sig)} "
        f"follow it ({what}; it would read as rate random walk)"
    )
    if remove:
        coef = np.array([drifts[j].coefficient if drifts[j].significant else 0.0
                         for j in range(len(channels))])  # fmt: skip
    return coef, [note]


def _phases_of(
    source: Blocks,
    coef: np.ndarray,
    xbar: np.ndarray,
    tbar: float,
    rate: float,
    phases: Callable[[], PhaseStore],
    k: int,
) -> list[PhaseStore]:
    """The phase of each channel less its temperature line: cumulative sums carried across
    the blocks (the sum of the line's term over the recording is 0), one store each."""
    stores = [phases() for _ in range(k)]
    carry = np.zeros(k)
    for s in stores:
        s.append(np.zeros(1))
    for _, x, tc in source.blocks():
        for j in range(k):
            col = x[:, j] - coef[j] * (tc - tbar) if coef[j] and tc is not None else x[:, j]
            cs = np.cumsum(np.concatenate([[carry[j]], col - xbar[j]]))[1:]
            carry[j] = cs[-1] if cs.size else carry[j]
            stores[j].append(cs / rate)
    return stores


def plan(
    analysis: NoiseAnalysis, precision: float, ci: float | None = None
) -> dict[str, dict[str, float | None]]:
    """Per quantity and channel: the recording length (s) that gives the figure to
    ±``precision`` (relative) at the analysis's confidence level, from the fitted model."""
    out: dict[str, dict[str, float | None]] = {q: {} for q in QUANTITIES}
    for name, ch in analysis.channels.items():
        for k, q in enumerate(QUANTITIES):
            out[q][name] = plan_duration(ch.coef, k, precision, analysis.rate_hz, ci or analysis.ci)
    return out


# --------------------------------------------------------------------------- noise files
def model_from_dict(doc: Mapping[str, Any], source: str = "noise file") -> dict[str, np.ndarray]:
    """Per channel the model (N², B², K²) of a noise document (:meth:`NoiseAnalysis.as_dict`);
    an unresolved figure counts at its upper bound (the conservative floor)."""
    if not isinstance(doc, Mapping) or doc.get("format") != "imu-bench noise":
        raise ValueError(f"{source}: not an imu-bench noise file (key 'format')")
    v = doc.get("format_version")
    if not isinstance(v, int) or isinstance(v, bool) or v > NOISE_FORMAT_VERSION:
        raise ValueError(
            f"{source}: noise format v{v} is not one this program reads "
            f"(v{NOISE_FORMAT_VERSION}); update the host software"
        )
    out: dict[str, np.ndarray] = {}
    for name, figs in dict(doc.get("channels", {})).items():
        coef = np.zeros(3)
        for k, q in enumerate(QUANTITIES):
            f = figs[q]
            val = f["value"] if f["value"] is not None else f["ci"][1]
            coef[k] = float(val) ** 2
        out[str(name)] = coef
    return out


def record_mean_floor(doc: Mapping[str, Any], duration_s: float) -> dict[str, float]:
    """Per channel the standard deviation by which the means of two successive static records
    of ``duration_s`` s differ per √2 — the Allan deviation of the noise model at
    τ = ``duration_s`` (channel unit). This is the workbench's noise floor of a record mean."""
    if not duration_s > 0:
        raise ValueError("duration_s must be positive")
    tau = np.array([float(duration_s)])
    return {
        name: float(np.sqrt(basis(tau) @ coef)[0]) for name, coef in model_from_dict(doc).items()
    }


def workbench_floor(doc: Mapping[str, Any], duration_s: float) -> dict[str, float]:
    """Per sensor ('accel' m/s², 'gyro' °/s) how far the mean of a ``duration_s`` s record
    wanders in ways its own samples cannot show: the Allan variance of the noise model at
    τ = ``duration_s`` without its white part (B²·2·ln2/π + K²·τ/3, :func:`allan.basis`),
    the largest of the sensor's three channels. This is the workbench's ``--noise`` floor:
    each record measures its white noise itself, so that part is not counted twice."""
    if not duration_s > 0:
        raise ValueError("duration_s must be positive")
    row = basis(np.array([float(duration_s)]))[0]
    row[0] = 0.0  # the white part: the record's own samples give it
    out: dict[str, float] = {}
    for name, coef in model_from_dict(doc).items():
        s = sensor_of(name)
        out[s] = max(out.get(s, 0.0), float(np.sqrt(max(float(row @ coef), 0.0))))
    return out


# --------------------------------------------------------------------------- display units
def display_units(channel: str, q: str, value: float) -> tuple[float, str]:
    """A figure in the unit users quote: gyro white noise °/√h, bias instability °/h, rate
    random walk °/h/√h; accelerometer µg/√Hz, µg, µg/√s·… (m/s/√h for velocity random walk
    is in :func:`secondary_units`)."""
    if sensor_of(channel) == "gyro":
        factor, unit = {
            "white_noise_density": (60.0, "°/√h"),
            "bias_instability": (3600.0, "°/h"),
            "rate_random_walk": (3600.0 * 60.0, "°/h/√h"),
        }[q]
    else:
        factor, unit = {
            "white_noise_density": (1e6 / G0, "µg/√Hz"),
            "bias_instability": (1e6 / G0, "µg"),
            "rate_random_walk": (1e6 / G0, "µg/√s"),
        }[q]
    return value * factor, unit


def secondary_units(channel: str, q: str, value: float) -> tuple[float, str] | None:
    """A second display unit where users quote two: accelerometer white noise as velocity
    random walk in m/s/√h."""
    if sensor_of(channel) == "accel" and q == "white_noise_density":
        return value * 60.0, "m/s/√h"
    return None


def load_noise_file(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a noise file written by ``noise --save`` (for the workbench's noise floor: pass the
    result to :func:`record_mean_floor`); raises UserError naming the problem."""
    p = Path(path)
    try:
        doc = load_json(p.read_bytes())
        model_from_dict(doc, str(p))
    except FileNotFoundError:
        raise UserError(f"{p}: no such noise file (write one with: noise FILE --save)") from None
    except OSError as exc:
        raise UserError(f"{p}: cannot read the noise file ({exc.strerror or exc})") from None
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise UserError(f"{p}: not a readable noise file ({exc})") from None
    return dict(doc)
