"""Thermal calibration's result: each channel's bias (and accelerometer scale) against chip
temperature, and how it is used.

Per channel the model is (method.md §8, "parameters drift with temperature … fits bias(T)")::

    reading = offset[attitude] + Σ_{j=1..k} c_j·(T − T_ref)^j

The polynomial is the bias *change* with temperature, so a result applies on top of the
ordinary calibration made at ``T_ref`` (the mean temperature of the six static records, when
present). :class:`ThermalCalibration` is the versioned result (coefficients, their covariance,
the temperature range over which they hold, ``SERIAL_thermal.json``); :func:`apply_thermal`
removes the bias change and warns outside that range; :func:`corrected_records` gives records
as they would read at another reference temperature. The fit that makes it, from records, is
:mod:`host.calib.thermal_fit`.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from host.errors import UserError
from host.session.inputs import check_serial, load_json
from host.session.records import Record

CHANNELS = ("ax", "ay", "az", "gx", "gy", "gz")
UNITS = ("m/s^2", "m/s^2", "m/s^2", "deg/s", "deg/s", "deg/s")
#: confidence level of the band around bias(T)
BAND_LEVEL = 0.95


class ThermalRangeWarning(UserWarning):
    """:func:`apply_thermal` was given temperatures outside the calibrated range."""


def change_from_reference(coef: tuple[float, ...], temp_c: np.ndarray, t_ref: float) -> np.ndarray:
    """Σ_j c_j·(T − T_ref)^j for j = 1…len(coef) at ``temp_c`` (°C): the change from the value
    at T_ref, in the unit of the coefficients times °C^j (the module's polynomial model of
    method.md §8, without its constant term)."""
    d = np.asarray(temp_c, dtype=np.float64) - t_ref
    out = np.zeros_like(d)
    for j, c in enumerate(coef, start=1):
        out += c * d**j
    return out


@dataclass(frozen=True)
class ChannelThermal:
    """bias(T) − bias(T_ref) of one channel: ``coef`` c_1..c_k (unit/°C^j), ``cov`` their
    covariance (from the fit with the bias wander), ``rms`` of the residual (unit), and the
    selection table ``bic`` / ``heldout_rmse`` per order 0..max."""

    channel: str
    unit: str
    order: int
    coef: tuple[float, ...]
    cov: tuple[tuple[float, ...], ...]
    rms: float
    bic: tuple[float, ...]
    heldout_rmse: tuple[float, ...]
    #: scale change with temperature (accelerometer, where the attitudes allow): the reading
    #: gains s_q·(T − T_ref)^q times the specific force along the axis; ``scale_coef`` s_1..s_q
    #: (1/°C^q), ``scale_cov`` their covariance, ``scale_bic`` the selection table per order
    scale_order: int = 0
    scale_coef: tuple[float, ...] = ()
    scale_cov: tuple[tuple[float, ...], ...] = ()
    scale_bic: tuple[float, ...] = ()

    def scale_delta(self, temp_c: np.ndarray, t_ref: float) -> np.ndarray:
        """Relative scale change at ``temp_c`` (°C) from T_ref (dimensionless)."""
        return change_from_reference(self.scale_coef, temp_c, t_ref)

    def delta(self, temp_c: np.ndarray, t_ref: float) -> np.ndarray:
        """Bias change at ``temp_c`` (°C) from T_ref, channel unit."""
        return change_from_reference(self.coef, temp_c, t_ref)

    def band(self, temp_c: np.ndarray, t_ref: float) -> np.ndarray:
        """Half-width of the simultaneous 95 % band of :meth:`delta` at ``temp_c`` (channel
        unit): the whole true curve lies inside it with 95 % confidence (Scheffé: the
        chi-squared quantile with one degree of freedom per coefficient)."""
        from scipy.stats import chi2

        d = np.asarray(temp_c, dtype=np.float64) - t_ref
        if not self.coef:
            return np.zeros_like(d)
        g = np.column_stack([d**j for j in range(1, len(self.coef) + 1)])
        cov = np.array(self.cov)
        z = math.sqrt(float(chi2.ppf(BAND_LEVEL, len(self.coef))))
        return z * np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", g, cov, g), 0.0))


def recentred(ch: ChannelThermal, t_from: float, t_to: float) -> tuple[np.ndarray, np.ndarray]:
    """The same bias change about another reference temperature: Σ_j c_j·(T − t_from)^j less
    its value at ``t_to`` = Σ_i c̃_i·(T − t_to)^i, with c̃_i = Σ_{j≥i} C(j, i)·δ^(j−i)·c_j,
    δ = t_to − t_from (°C). Returns c̃ (k,) and its covariance (k, k) (the map is linear)."""
    return recentre_poly(ch.coef, ch.cov, t_from, t_to)


def recentre_poly(
    coef: Sequence[float], cov: Sequence[Sequence[float]], t_from: float, t_to: float
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`recentred` for any polynomial without constant term: coefficients c_1..c_k
    about ``t_from`` and their covariance -> the same about ``t_to``, constant dropped."""
    k = len(coef)
    delta = t_to - t_from
    r = np.zeros((k, k))
    for j in range(1, k + 1):
        for i in range(1, j + 1):
            r[i - 1, j - 1] = math.comb(j, i) * delta ** (j - i)
    c = r @ np.array(coef, dtype=np.float64).reshape(k)
    cv = r @ np.array(cov, dtype=np.float64).reshape(k, k) @ r.T
    return c, cv


@dataclass(frozen=True)
class ThermalCalibration:
    """The thermal result: per channel :class:`ChannelThermal`, the reference temperature
    ``t_ref_c`` and the range ``[t_min_c, t_max_c]`` (°C) over which the coefficients hold."""

    FORMAT_VERSION: ClassVar[int] = 2
    #: format versions this program reads (v1: bias(T) only)
    READS: ClassVar[tuple[int, ...]] = (1, 2)

    serial: str
    t_ref_c: float
    t_min_c: float
    t_max_c: float
    channels: dict[str, ChannelThermal]
    attitudes: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": "imu-bench thermal",
            "format_version": self.FORMAT_VERSION,
            "serial": self.serial,
            "model": "bias(T) - bias(T_ref) = sum_j c_j (T - T_ref)^j, T in degC; accelerometer "
            "scale: reading += sum_q s_q (T - T_ref)^q * specific force along the axis",
            "t_ref_c": self.t_ref_c,
            "valid_range_c": [self.t_min_c, self.t_max_c],
            "attitudes": list(self.attitudes),
            "channels": {
                name: {
                    "order": ch.order,
                    "coefficients": list(ch.coef),
                    "units": [f"{ch.unit}/degC^{j}" for j in range(1, ch.order + 1)],
                    "covariance": [list(r) for r in ch.cov],
                    "rms": ch.rms,
                    "selection": {"bic": list(ch.bic), "heldout_rmse": list(ch.heldout_rmse)},
                    "scale": {
                        "order": ch.scale_order,
                        "coefficients": list(ch.scale_coef),
                        "units": [f"1/degC^{q}" for q in range(1, ch.scale_order + 1)],
                        "covariance": [list(r) for r in ch.scale_cov],
                        "selection": {"bic": list(ch.scale_bic)},
                    },
                }
                for name, ch in self.channels.items()
            },
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2) + "\n"

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> ThermalCalibration:
        """Read ``SERIAL_thermal.json``; UserError naming the file when it cannot."""
        try:
            d = load_json(Path(path).read_bytes())
        except (OSError, ValueError) as exc:
            raise UserError(f"{path}: cannot read a thermal result ({exc})") from None
        return cls.from_dict(d, str(path))

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], source: str = "thermal result") -> ThermalCalibration:
        if not isinstance(d, Mapping) or d.get("format") != "imu-bench thermal":
            raise UserError(f"{source}: not an imu-bench thermal result")
        v = d.get("format_version")
        if v not in cls.READS:
            raise UserError(
                f"{source}: thermal result format v{v}, this program reads "
                f"v{cls.FORMAT_VERSION}; update the host software or refit"
            )
        try:
            chans = {}
            for j, name in enumerate(CHANNELS):
                c = d["channels"][name]
                sc = c.get("scale") or {}
                chans[name] = ChannelThermal(
                    name,
                    UNITS[j],
                    int(c["order"]),
                    tuple(float(x) for x in c["coefficients"]),
                    tuple(tuple(float(x) for x in r) for r in c["covariance"]),
                    float(c["rms"]),
                    tuple(float(x) for x in c["selection"]["bic"]),
                    tuple(float(x) for x in c["selection"]["heldout_rmse"]),
                    int(sc.get("order", 0)),
                    tuple(float(x) for x in sc.get("coefficients", ())),
                    tuple(tuple(float(x) for x in r) for r in sc.get("covariance", ())),
                    tuple(float(x) for x in sc.get("selection", {}).get("bic", ())),
                )
            lo, hi = (float(x) for x in d["valid_range_c"])
            serial = check_serial(str(d["serial"]), "its serial")
            return cls(serial, float(d["t_ref_c"]), lo, hi, chans, tuple(d["attitudes"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise UserError(f"{source}: damaged thermal result ({exc})") from None


def apply_thermal(
    cal: ThermalCalibration, accel: np.ndarray, gyro: np.ndarray, temp_c: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Remove the bias change with temperature: ``accel`` (N, 3) m/s², ``gyro`` (N, 3) °/s,
    ``temp_c`` (N,) chip °C -> the readings as at T_ref (then apply the ordinary calibration).
    Warns (:class:`ThermalRangeWarning`) for temperatures outside the calibrated range, where
    the polynomial is extrapolated."""
    t = np.asarray(temp_c, dtype=np.float64).reshape(-1)
    a = np.array(accel, dtype=np.float64).reshape(t.size, 3)
    g = np.array(gyro, dtype=np.float64).reshape(t.size, 3)
    outside = (t < cal.t_min_c) | (t > cal.t_max_c)
    if np.any(outside):
        warnings.warn(
            f"{int(np.count_nonzero(outside))} samples at {float(t.min()):.1f} to "
            f"{float(t.max()):.1f} °C lie outside the thermal calibration's range "
            f"{cal.t_min_c:.1f} to {cal.t_max_c:.1f} °C: the bias(T) polynomial is "
            "extrapolated there",
            ThermalRangeWarning,
            stacklevel=2,
        )
    for j, name in enumerate(CHANNELS):
        ch = cal.channels[name]
        target = a if j < 3 else g
        target[:, j % 3] -= ch.delta(t, cal.t_ref_c)
        if ch.scale_order:
            target[:, j % 3] /= 1.0 + ch.scale_delta(t, cal.t_ref_c)
    return a, g


def corrected_records(
    records: Mapping[str, Record], cal: ThermalCalibration, t_ref_c: float
) -> dict[str, Record]:
    """The records less the bias change from ``t_ref_c`` (°C) to each sample's chip
    temperature: what they would read at ``t_ref_c`` (the calibration of such records is the
    calibration at ``t_ref_c``; ``thermal_bias`` about ``t_ref_c`` adds the change back)."""
    out: dict[str, Record] = {}
    for name, rec in records.items():
        a, g = rec.accel.copy(), rec.gyro.copy()
        for j, ch_name in enumerate(CHANNELS):
            ch = cal.channels[ch_name]
            d = rec.temp - t_ref_c
            if ch.order:
                c, _ = recentred(ch, cal.t_ref_c, t_ref_c)
                (a if j < 3 else g)[:, j % 3] -= sum(ci * d ** (i + 1) for i, ci in enumerate(c))
            if ch.scale_order:
                s_c, _ = recentre_poly(ch.scale_coef, ch.scale_cov, cal.t_ref_c, t_ref_c)
                (a if j < 3 else g)[:, j % 3] /= 1.0 + sum(
                    si * d ** (i + 1) for i, si in enumerate(s_c)
                )
        out[name] = dataclasses.replace(rec, accel=a, gyro=g)
    return out
