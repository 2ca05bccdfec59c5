"""The model workbench's engine: a sensor model is a list of named physical terms.

Each :class:`Term` carries its physics (docstring), the sensor it acts on ("accel"/"gyro"), its
parameters with units and a function building its columns of the design matrix from the
records' reference signals (:class:`RecordSignals`: reference specific force, reference rate,
chip temperature, time since power-on). ``base`` = bias + scale + misalignment + g_sensitivity
is the linear model of method.md §2; the other catalogue terms are the effects §8 says a
residual analysis should look for (temperature, drift, nonlinearity …).

The fit (:func:`fit_model`) is ONE weighted linear least-squares problem over every record:

* static (and rate-table) records are cut into blocks of ``NoiseModel.block_s`` seconds; each
  block mean of each channel is a row, so temperature and time terms see within-record variation
  as well as the differences between records;
* each turn record gives one row per gyro channel, the trapezoid integral (method.md §4), in °;
* accelerometer rows of a turn record: one per still moment (gravity at another heading) and, on
  the horizontal channels, one per moving block (:mod:`host.modelling.turning`: the lever arm's
  centripetal and tangential acceleration, with the hand's scatter measured from the blocks).

Noise model (:class:`NoiseModel`, method.md §8 "residual mean near 0"): the rows of one
record and channel share one covariance ``v·I + f²·11ᵀ``: ``v`` = variance of a block mean from
the record's own samples (pooled within-block variance × integrated autocorrelation time, at least
the quantisation step²/12), ``f`` = the bias-instability floor: the slow Gauss-Markov wander of
a MEMS bias moves each record's mean by an amount the record itself cannot show. The rows are
whitened exactly (record mean + orthonormal within-record contrasts); χ² is then honest under the
null and needs no inflation. Turn integrals: white noise integrated + (floor·T)² + the hand's
angle error (``turn_angle_sigma_deg``, as :mod:`host.calibration`).

Terms nonlinear in their parameters (``Term.value``) are linearised around the current
estimate (numerical Jacobian) and the fit iterated (Gauss-Newton).

Length (over 600 lines): the workbench engine is three parts — the term catalogue, the dataset and
noise model, the fit — that should be three modules; left whole while issues 11, 12 and 16
change it in parallel (a split now would collide with each of them). Splitting it is the
next step of issue 14.
"""

from __future__ import annotations

import functools
import importlib.util
import inspect
import math
import sys
from collections.abc import Callable, Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from host.errors import UserError
from host.modelling import turning
from host.session.directory import Session
from host.session.method import (
    DEFAULT_HEIGHT_M,
    DEFAULT_LATITUDE_DEG,
    TURN_ANGLE_SIGMA_DEG,
    local_gravity,
    record_stats,
    trapezoid_integral,
)
from host.session.observations import build_observations

SENSORS = ("accel", "gyro")
AXES = "xyz"
#: unit of each sensor's output and of its reference input
UNIT = {"accel": "m/s²", "gyro": "°/s"}
#: chip temperature the temperature terms are referred to, °C (the simulator's ``temp_ref_c``)
TEMP_REF_C = 25.0


# ---- reference signals ----------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class RecordSignals:
    """Per-sample signals of one record, the inputs the terms build their columns from.

    ``t_s`` (N,) s since power-on (meta ``power_on_s`` + sample time; when a record does not
    say, time from the record's middle), ``temp_c`` (N,) chip °C, ``force`` (N,3) reference
    specific force m/s² (g along the up direction), ``rate`` (N,3) reference rate °/s (zero for
    statics; for a turn the measured profile about the up axis scaled to the known ±360·n°),
    ``accel``/``gyro`` (N,3) the measured outputs. ``g`` m/s². ``temp_mean_c``: mean chip
    temperature of the whole session, °C. ``heading_deg`` (N,) the angle the cube has turned
    about its up axis since the record began, ° (positive counter-clockwise seen from above;
    None: it did not turn, 0).
    """

    name: str
    kind: str
    t_s: np.ndarray
    temp_c: np.ndarray
    force: np.ndarray
    rate: np.ndarray
    accel: np.ndarray
    gyro: np.ndarray
    g: float
    up: np.ndarray
    temp_mean_c: float = TEMP_REF_C
    heading_deg: np.ndarray | None = None

    def reference(self, sensor: str) -> np.ndarray:
        """(N,3) the true input of ``sensor``: specific force m/s² or rate °/s."""
        return self.force if sensor == "accel" else self.rate

    def measured(self, sensor: str) -> np.ndarray:
        """(N,3) the measured output of ``sensor``."""
        return self.accel if sensor == "accel" else self.gyro

    @property
    def hours(self) -> np.ndarray:
        """(N,) hours since power-on."""
        return self.t_s / 3600.0

    @property
    def d_temp(self) -> np.ndarray:
        """(N,) chip temperature − :data:`TEMP_REF_C`, °C."""
        return self.temp_c - TEMP_REF_C

    @property
    def heading(self) -> np.ndarray:
        """(N,) :attr:`heading_deg` in rad (zeros when the record did not turn)."""
        if self.heading_deg is None:
            return np.zeros(len(self.t_s))
        return np.radians(self.heading_deg)


# ---- terms ----------------------------------------------------------------------------------
ColumnFn = Callable[[RecordSignals, str, int], np.ndarray]
ValueFn = Callable[[RecordSignals, str, int, np.ndarray], np.ndarray]
CheckFn = Callable[[Sequence[RecordSignals]], "str | None"]
LabelFn = Callable[[str, int], tuple[str, ...]]


@dataclass(frozen=True, eq=False)
class Term:
    """One physical effect of the sensor model.

    ``columns(signals, sensor, axis)`` -> (N, k) per-sample regressors of output channel
    ``axis`` of ``sensor`` (in that channel's unit per unit parameter); the fit aggregates them
    like the measurements (block means, turn integrals). ``units``: one template per parameter,
    ``{u}`` = the channel's unit. ``needs``: what data would make the term identifiable;
    ``check``: returns why the records cannot determine it (or None). A term nonlinear in its
    parameters gives ``value(signals, sensor, axis, theta)`` -> (N,) instead, and ``initial``.
    """

    name: str
    doc: str
    sensors: tuple[str, ...]
    params: tuple[str, ...]
    units: tuple[str, ...]
    columns: ColumnFn | None = None
    needs: str = ""
    check: CheckFn | None = None
    labels: LabelFn | None = None
    value: ValueFn | None = None
    initial: tuple[float, ...] = ()
    #: largest plausible |parameter| per sensor (in the parameter's unit) and where that
    #: figure comes from; a fitted value beyond it is not a physical reading of the term
    plausible: Mapping[str, float] = field(default_factory=dict)
    plausible_source: str = ""
    #: one set of parameters for every channel the term acts on (a property of the bench, e.g.
    #: the plate's tilt, not of one output channel): the channels' columns share them
    shared: bool = False

    @property
    def physics(self) -> str:
        """The one-line physical explanation (first line of the docstring)."""
        return self.doc.strip().splitlines()[0] if self.doc.strip() else ""

    @property
    def nonlinear(self) -> bool:
        return self.value is not None

    def param_labels(self, sensor: str, axis: int) -> tuple[str, ...]:
        """Names of the parameters on channel ``axis`` of ``sensor`` (§2 names for base terms;
        a :attr:`shared` term's names do not depend on ``axis``)."""
        if self.labels is not None:
            return self.labels(sensor, axis)
        stem = f"{self.name}.{sensor}" + ("" if self.shared else f".{AXES[axis]}")
        return tuple(stem if len(self.params) == 1 else f"{stem}.{p}" for p in self.params)

    def param_units(self, sensor: str) -> tuple[str, ...]:
        """Units of the parameters for ``sensor``."""
        return tuple(u.replace("{u}", UNIT[sensor]) for u in self.units)


def term(
    *,
    sensors: Sequence[str] = SENSORS,
    params: Mapping[str, str] | None = None,
    needs: str = "",
    check: CheckFn | None = None,
    labels: LabelFn | None = None,
    name: str | None = None,
) -> Callable[[ColumnFn], Term]:
    """Decorator turning a column function into a :class:`Term` (see the README's example).

    ``params``: parameter name -> unit template (``{u}`` = the channel's unit); default one
    parameter in the channel's unit. The function's docstring is the term's physics.
    """
    pmap = dict(params) if params is not None else {"c": "{u}"}

    def wrap(fn: ColumnFn) -> Term:
        doc = inspect.getdoc(fn) or ""
        if not doc:
            raise UserError(f"term {fn.__name__}: give it a docstring with the physics")
        bad = [s for s in sensors if s not in SENSORS]
        if bad or not pmap:
            raise UserError(f"term {fn.__name__}: sensors must be accel/gyro, params non-empty")
        return Term(
            name=name or fn.__name__, doc=doc, sensors=tuple(sensors), params=tuple(pmap),
            units=tuple(pmap.values()), columns=fn, needs=needs, check=check, labels=labels,
        )  # fmt: skip

    return wrap


def nonlinear_term(
    *,
    initial: Sequence[float],
    sensors: Sequence[str] = SENSORS,
    params: Mapping[str, str] | None = None,
    needs: str = "",
    check: CheckFn | None = None,
    name: str | None = None,
) -> Callable[[ValueFn], Term]:
    """Decorator for a term nonlinear in its parameters: the function gives the term's
    per-sample contribution ``value(signals, sensor, axis, theta)`` (N,); the fit linearises it
    around the current estimate (starting at ``initial``) and iterates."""
    pmap = dict(params) if params is not None else {"c": "{u}"}

    def wrap(fn: ValueFn) -> Term:
        doc = inspect.getdoc(fn) or ""
        if not doc:
            raise UserError(f"term {fn.__name__}: give it a docstring with the physics")
        if len(initial) != len(pmap):
            raise UserError(f"term {fn.__name__}: one initial value per parameter")
        return Term(
            name=name or fn.__name__, doc=doc, sensors=tuple(sensors), params=tuple(pmap),
            units=tuple(pmap.values()), value=fn, needs=needs, check=check,
            initial=tuple(float(x) for x in initial),
        )  # fmt: skip

    return wrap


# ---- the catalogue --------------------------------------------------------------------------
#: position of each §2 name in M (row = channel, column = input axis) and its sign
_LAYOUT: dict[str, tuple[int, int, int]] = {
    "xx": (0, 0, 1), "xz": (0, 1, 1), "xy": (0, 2, -1),
    "yz": (1, 0, -1), "yy": (1, 1, 1), "yx": (1, 2, 1),
    "zy": (2, 0, 1), "zx": (2, 1, -1), "zz": (2, 2, 1),
}  # fmt: skip
_PREFIX = {"accel": "A", "gyro": "G"}


def _off_diagonal(axis: int) -> list[tuple[str, int, int]]:
    """(§2 suffix, input axis, sign) of the two misalignments of channel ``axis``."""
    return [(s, k, sg) for s, (i, k, sg) in _LAYOUT.items() if i == axis and k != axis]


#: a temperature coefficient needs the chip temperature to span at least this much, °C: over a
#: narrower span drift, wander and noise pass for a coefficient many times the datasheet's
MIN_TEMP_SPAN_C = 2.0


def _temperature_check(signals: Sequence[RecordSignals]) -> str | None:
    temps = np.concatenate([s.temp_c for s in signals]) if signals else np.zeros(1)
    lo, hi = float(np.min(temps)), float(np.max(temps))
    if hi - lo < MIN_TEMP_SPAN_C:
        return f"chip temperature spans only {hi - lo:.1f} °C ({lo:.1f} … {hi:.1f} °C)" + (
            " — a constant: it was probably not measured" if hi == lo else ""
        )
    return None


_TEMP_NEEDS = (
    "records at chip temperatures a few °C apart (measure during warm-up, or repeat the "
    "attitudes in a warmer/colder room), with the temperature not rising steadily with time"
)


@term(params={"bias": "{u}"}, needs="static records", labels=lambda s, i: (
    f"{_PREFIX[s]}0{AXES[i]}",))  # fmt: skip
def bias(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Constant offset of the output (method.md §2 A0., G0.): the zero-input reading."""
    return np.ones((len(sig.t_s), 1))


@term(params={"scale": "1"}, needs="inputs of both signs on this axis (±1 g faces; CW and CCW "
      "turns about the axis)", labels=lambda s, i: (f"{_PREFIX[s]}{AXES[i] * 2}",))  # fmt: skip
def scale(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Relative scale-factor error (method.md §2 Axx, Gxx): output = (1 + s)·input."""
    return sig.reference(sensor)[:, axis : axis + 1]


def _mis_labels(sensor: str, axis: int) -> tuple[str, ...]:
    return tuple(f"{_PREFIX[sensor]}{s}" for s, _, _ in _off_diagonal(axis))


@term(params={"m1": "rad", "m2": "rad"}, labels=_mis_labels,
      needs="inputs along the other two axes (gravity along them; turns about them)")  # fmt: skip
def misalignment(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Small-angle axis misalignment (method.md §2 Axz, Axy …): the channel also senses the
    input along the other two axes, with the signs of §2."""
    ref = sig.reference(sensor)
    return np.column_stack([sg * ref[:, k] for _, k, sg in _off_diagonal(axis)])


@term(sensors=("gyro",), params={"gx": "(°/s)/g", "gy": "(°/s)/g", "gz": "(°/s)/g"},
      labels=lambda s, i: tuple(f"GA{AXES[i]}{b}" for b in AXES),
      needs="static records with gravity along each axis")  # fmt: skip
def g_sensitivity(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Gyro bias proportional to the specific force (method.md §2 GA..): the proof mass of a
    vibrating MEMS gyro is displaced by acceleration, (°/s) per g along x, y, z."""
    return sig.force / sig.g


@term(params={"per_C": "{u}/°C"}, needs=_TEMP_NEEDS, check=_temperature_check)
def temperature_bias(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Bias linear in chip temperature: thermal stress in the MEMS die and the readout's
    temperature coefficient shift the zero, b·(T − 25 °C) (method.md §8)."""
    return sig.d_temp[:, None]


@term(params={"per_C2": "{u}/°C²"}, needs=_TEMP_NEEDS, check=_temperature_check)
def temperature_bias_quadratic(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Bias quadratic in chip temperature, b2·(T − T̄)² about the session's mean temperature:
    the curvature of bias(T) (method.md §8's 20-temperature procedure fits bias(T))."""
    return ((sig.temp_c - sig.temp_mean_c) ** 2)[:, None]


@term(params={"per_C": "1/°C"}, needs=_TEMP_NEEDS + " and large inputs (±1 g, turns)",
      check=_temperature_check)  # fmt: skip
def temperature_scale(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Scale factor linear in chip temperature: the spring constant and the drive amplitude
    change with temperature, output += s_T·(T − 25 °C)·input."""
    return (sig.d_temp * sig.reference(sensor)[:, axis])[:, None]


@term(
    params={"per_h": "{u}/h"},
    needs="records spread over time since power-on (meta "
    "power_on_s) or long records, with the temperature not rising steadily with time",
)
def time_drift(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Bias linear in time since power-on, d·t: slow settling of the electronics and
    charging/outgassing of the package, at constant temperature (warm-up drift)."""
    return sig.hours[:, None]


@term(
    params={"asym": "1"},
    needs="inputs of several magnitudes on this axis (for the "
    "accelerometer the 45° attitudes tilt_45_*, for the gyro turns at several rates)",
)
def scale_asymmetry(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Different scale for positive and negative input (scale(+) − scale(−) = asym): an
    asymmetric proof-mass suspension or readout, output += ½·asym·|input|."""
    return 0.5 * np.abs(sig.reference(sensor)[:, axis : axis + 1])


@term(
    params={"k2": "1/({u})"},
    needs="inputs of several magnitudes on this axis (for the "
    "accelerometer the 45° attitudes tilt_45_*, for the gyro turns at several rates)",
)
def scale_nonlinearity(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Output quadratic in the input, k2·input²: the nonlinear spring/capacitance of the MEMS
    transducer (the datasheet's nonlinearity, % of full scale)."""
    return sig.reference(sensor)[:, axis : axis + 1] ** 2


# ---- placement and geometry: attitudes that are not exactly the nominal ones ---------------
def _face(sig: RecordSignals) -> tuple[int, int] | None:
    """(axis, ±1) of the fixture face a static or turn record rests on (its up axis), None for
    a rate-table record or an attitude that is not one of the six faces (e.g. tilt_45_*)."""
    if sig.kind not in ("static", "turn"):  # a turn: the cube turns resting on that face
        return None
    k = int(np.argmax(np.abs(sig.up)))
    if abs(abs(float(sig.up[k])) - 1.0) > 1e-6:
        return None
    return k, 1 if sig.up[k] > 0 else -1


def _other_axes(axis: int) -> tuple[int, int]:
    a, b = (k for k in range(3) if k != axis)
    return a, b


_FACE_NEEDS = (
    "attitudes that are not the six faces (the 45° attitudes tilt_45_*), or the same faces "
    "measured again after turning the board 90° in the fixture (a fixture error moves with the "
    "fixture, a sensor effect with the sensor)"
)


@term(sensors=("accel",), params={"pair_a": "rad", "pair_b": "rad"}, needs=_FACE_NEEDS,
      labels=lambda s, i: tuple(f"face_error.accel.{AXES[i]}.±{AXES[k]}"
                                for k in _other_axes(i)))  # fmt: skip
def face_error(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Fixture faces not square to the sensor's axes put part of gravity on a horizontal axis.

    Resting on face ±j, the cube stands tilted by θ toward axis i and accelerometer i reads
    g·sin θ ≈ g·θ (rad) of gravity that nominally is all on j.

    One angle per channel and face PAIR (the mean of the two opposite faces; their difference
    acts exactly like the misalignment A_ij and is counted there). This is what makes the three
    §3 bias estimates of a channel disagree: the pairs in which the channel is horizontal get
    g·θ added. On the six faces alone it is indistinguishable from a sensor reading the square
    of a cross-axis specific force (k·a_j², identical at ±1 g)."""
    face = _face(sig)
    cols = np.zeros((len(sig.t_s), 2))
    if face is not None:
        for c, k in enumerate(_other_axes(axis)):
            if face[0] == k:
                cols[:, c] = sig.g
    return cols


def _placement(up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(east, north) of the fixture frame in body axes for a cube resting with body ``up`` up,
    the program's placement convention: the first body axis (x, y, z order) that is not along
    up lies along the ruler (east), north = up × east (:func:`host.sim_physics.pose_from_up`)."""
    from host.bench.physics import pose_from_up

    r = pose_from_up(up)
    return r[0], r[1]


@term(sensors=("accel",), params={"tilt_east": "rad", "tilt_north": "rad"},
      labels=lambda s, i: ("plate_tilt.east", "plate_tilt.north"),
      needs="the accelerometer at several headings on the plate (the still moments inside the "
      "turn records, a quarter turn or more apart), or static attitudes beyond the six faces "
      "(tilt_45_*)")  # fmt: skip
def plate_tilt(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """A base plate that is not level: gravity leans by the same two angles in every record.

    ONE pair of small angles (rad) for the whole session, in the plate's frame: gravity's
    up direction leans ``tilt_east`` toward the ruler (east) and ``tilt_north`` toward
    north = up × east. The plate does not move, so the angles are shared by every record made
    on it and by all three accelerometer channels (:attr:`Term.shared`). Resting on a face, the
    horizontal accelerometers read g·(tilt_east·e + tilt_north·n), with e, n the plate's axes
    in body coordinates: at placement the first body axis not along up lies along the ruler.

    What tells it from a fixture-face error or a bias: the cube turning on the plate. A face
    error is fixed in the body, a plate tilt is fixed in the room: at heading ψ (turned ψ
    counter-clockwise about up since the placement) the plate's axes in the body are
    e(ψ) = e·cos ψ − n·sin ψ and n(ψ) = n·cos ψ + e·sin ψ, so at the still moments inside a
    turn record the horizontal accelerometers follow g·|tilt|·cos(ψ − ψ₀) while a face error,
    a bias and a misalignment stay put. On the six static faces alone the two angles act like
    accelerometer biases and misalignments (each face is one heading)."""
    cols = np.zeros((len(sig.t_s), 2))
    if sig.kind in ("static", "turn"):
        e0, n0 = _placement(sig.up)
        psi = sig.heading
        c, s = np.cos(psi), np.sin(psi)
        cols[:, 0] = sig.g * (e0[axis] * c - n0[axis] * s)
        cols[:, 1] = sig.g * (n0[axis] * c + e0[axis] * s)
    return cols


@term(sensors=("gyro",), params={"tilt_a": "rad", "tilt_b": "rad"},
      needs="turns about the same axis on a re-seated cube (a different face down, or the board "
      "turned in the fixture): a fixed tilt of the turn axis acts exactly like a misalignment",
      labels=lambda s, i: tuple(f"turn_axis_tilt.gyro.{AXES[i]}.turn_{AXES[k]}"
                                for k in _other_axes(i)))  # fmt: skip
def turn_axis_tilt(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """The turn axis tilted from the nominal up axis: an off-axis gyro sees part of the turn.

    The turn axis (the plate's normal, seen through the face the cube rests on) tilted from
    the nominal up axis j by θ toward axis i: gyro i sees θ·ω of a turn about j, so its
    integral over n turns is θ·360·n (rad → °/turn)."""
    cols = np.zeros((len(sig.t_s), 2))
    if sig.kind == "turn":
        k = int(np.argmax(np.abs(sig.up)))
        omega_up = sig.rate @ sig.up
        for c, j in enumerate(_other_axes(axis)):
            if j == k:
                cols[:, c] = omega_up
    return cols


def _lever_check(signals: Sequence[RecordSignals]) -> str | None:
    turns = [s for s in signals if s.kind == "turn"]
    if not turns:
        return "no turn records: a lever arm shows only while the cube turns"
    rms = max(turning.rms_rate_dps(s.rate @ s.up, [(0, len(s.t_s))]) for s in turns)
    if rms < turning.MIN_RATE_DPS:
        return (
            f"the turns reach only {rms:.0f} °/s RMS: ω²·r there is below the hand's scatter "
            f"(turn at {turning.MIN_RATE_DPS:.0f} °/s or faster)"
        )
    return None


@term(sensors=("accel",), params={"x": "m", "y": "m", "z": "m"}, check=_lever_check,
      labels=lambda s, i: ("lever_arm.x", "lever_arm.y", "lever_arm.z"),
      needs="turns about at least two axes at a brisk rate (≥ 30 °/s; each turn sees the two "
      "components of the offset perpendicular to its axis)")  # fmt: skip
def lever_arm(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """The sensor sits off the turn axis: turning, the accelerometer also reads ω̇×r + ω×(ω×r).

    ONE offset r = (x, y, z) m of the sensor from the cube's centre, in body axes, shared by
    every channel and every turn (:attr:`Term.shared`; geometry and physics in
    :mod:`host.modelling.turning`): the turns pivot about the vertical through the cube's
    centre, so a turn about up axis k adds the centripetal −ω²·r⊥ (r without its k component)
    and the tangential ω̇·(e_k × r) to the horizontal accelerometers, with ω the calibrated rate
    of the turn (the reference rate: the gyro about up scaled to ±360°·n, method.md §4) in
    rad/s. Read from the moving blocks of the turn records; zero at rest (static records, the
    still moments). 0.12 m/s² at 90 °/s and r = 5 cm."""
    if sig.kind != "turn":
        return np.zeros((len(sig.t_s), 3))
    return turning.lever_arm_matrix(sig.t_s, sig.rate)[:, axis, :]


#: plausible magnitude of each catalogue term's parameters per sensor, from the InvenSense
#: MPU-6000/6050 product specification rev. 3.4 (§6.1 gyro, §6.2 accelerometer) where it has a
#: figure, else from the bench (a levelled plate, a machined fixture)
_PLAUSIBLE: dict[str, tuple[dict[str, float], str]] = {
    "bias": ({"accel": 0.8, "gyro": 20.0},
             "datasheet: zero-g offset ±50 mg (X, Y), ±80 mg (Z); zero-rate output ±20 °/s"),
    "scale": ({"accel": 0.03, "gyro": 0.03},
              "datasheet: initial sensitivity tolerance ±3 %"),
    "misalignment": ({"accel": 0.02, "gyro": 0.02},
                     "datasheet: cross-axis sensitivity ±2 %"),
    "g_sensitivity": ({"gyro": 0.2}, "datasheet: linear acceleration sensitivity 0.1 (°/s)/g, "
                                     "×2"),
    "temperature_bias": ({"accel": 0.01, "gyro": 0.35},
                         "datasheet: zero-g offset change ±35 mg (X, Y) / ±60 mg (Z) and ZRO "
                         "variation ±20 °/s over −40…+85 °C, ×2, per °C"),
    "temperature_bias_quadratic": ({"accel": 3e-4, "gyro": 0.01},
                                   "the datasheet's whole offset change over −40…+85 °C as "
                                   "curvature about 25 °C, ×2"),
    "temperature_scale": ({"accel": 1e-3, "gyro": 1e-3},
                          "datasheet: accelerometer sensitivity change ±0.02 %/°C; gyro "
                          "sensitivity variation ±2 % over −40…+85 °C; ×5"),
    "time_drift": ({"accel": 0.5, "gyro": 5.0},
                   "warm-up drift of MEMS consumer IMUs: a fraction of the offset tolerance "
                   "per hour"),
    "scale_asymmetry": ({"accel": 0.02, "gyro": 0.02},
                        "datasheet: nonlinearity 0.5 % (accel) / 0.2 % (gyro) of full scale, ×4"),
    "scale_nonlinearity": ({"accel": 5e-4, "gyro": 4e-5},
                           "datasheet nonlinearity 0.5 % / 0.2 % of full scale as k2·FS² "
                           "(FS 19.6 m/s², 250 °/s), ×2"),
    "face_error": ({"accel": 0.0175},
                   "a fixture face out of square by more than 1° is not a machined fixture"),
    "plate_tilt": ({"accel": 0.0175}, "a plate more than 1° off level was not levelled"),
    "turn_axis_tilt": ({"gyro": 0.035}, "the turn axis more than 2° off the up axis: the cube "
                                        "was not resting on the plate"),
    "lever_arm": ({"accel": 0.1}, "a sensor more than 10 cm from the centre of a hand-held "
                                  "calibration cube is not inside the cube"),
}  # fmt: skip

#: catalogue terms whose parameters are properties of the bench, one set for all channels
_SHARED = ("plate_tilt", "lever_arm")

#: the built-in terms, in catalogue order
CATALOGUE: dict[str, Term] = {
    t.name: replace(t, plausible=_PLAUSIBLE[t.name][0], plausible_source=_PLAUSIBLE[t.name][1],
                    shared=t.name in _SHARED)
    for t in (
        bias, scale, misalignment, g_sensitivity, temperature_bias, temperature_bias_quadratic,
        temperature_scale, time_drift, scale_asymmetry, scale_nonlinearity, face_error,
        plate_tilt, turn_axis_tilt, lever_arm,
    )
}  # fmt: skip
#: the linear model of method.md §2
BASE = ("bias", "scale", "misalignment", "g_sensitivity")

#: highest polynomial order of bias(T) a result carries (the ``thermal`` command's limit)
THERMAL_MAX_ORDER = 6
_SUPERSCRIPT = {1: "", 2: "²", 3: "³", 4: "⁴", 5: "⁵", 6: "⁶"}


@term(
    params={
        f"per_C{'' if j == 1 else j}": f"{{u}}/°C{_SUPERSCRIPT[j]}"
        for j in range(1, THERMAL_MAX_ORDER + 1)
    },
    needs="a thermal calibration of the unit: python -m host thermal DIR (the warm-up record, "
    "a chamber ramp), then calibrate --thermal SERIAL_thermal.json",
)
def thermal_bias(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Bias change with chip temperature measured by the thermal calibration (``python -m host
    thermal``, method.md §8 "fits bias(T)"): Σ_j c_j·(T − T̄)^j about the session's mean chip
    temperature T̄, the order chosen per channel by that fit (coefficients not carried are 0)."""
    d = sig.temp_c - sig.temp_mean_c
    return np.column_stack([d**j for j in range(1, THERMAL_MAX_ORDER + 1)])


@term(
    sensors=("accel",),
    params={"per_C": "1/°C", "per_C2": "1/°C²"},
    needs="a thermal calibration with the axis up and down across the temperature span: "
    "python -m host thermal DIR --scale, then calibrate --thermal SERIAL_thermal.json",
)
def thermal_scale(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Accelerometer scale change with chip temperature measured by the thermal calibration
    (``python -m host thermal``): output += Σ_q s_q·(T − T̄)^q · input along the axis, about
    the session's mean chip temperature T̄ (coefficients not carried are 0)."""
    d = sig.temp_c - sig.temp_mean_c
    f = sig.reference(sensor)[:, axis]
    return np.column_stack([d * f, d * d * f])


#: terms whose values a result carries from a measurement of their own (not fitted to the
#: calibration records, not offered by the workbench); :func:`host.calib.result.apply`
#: evaluates them like every other term
CARRIED: dict[str, Term] = {t.name: t for t in (thermal_bias, thermal_scale)}


def load_term_file(
    path: str | Path, catalogue: Mapping[str, Term] | None = None
) -> dict[str, Term]:
    """Import a Python file of user terms (module-level :class:`Term` objects, e.g. made with
    :func:`term`) and return the catalogue extended by them. UserError on any failure."""
    p = Path(path)
    if not p.is_file():
        raise UserError(f"{p}: no such term file")
    mod_name = f"_imu_bench_terms_{abs(hash(str(p.resolve())))}"
    spec = importlib.util.spec_from_file_location(mod_name, p)
    if spec is None or spec.loader is None:
        raise UserError(f"{p}: cannot load it as Python")
    module = importlib.util.module_from_spec(spec)
    sys.modules[mod_name] = module
    try:
        spec.loader.exec_module(module)
    except UserError as exc:
        raise UserError(f"{p}: {exc}") from exc
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - user code: one line for the user
        raise UserError(f"{p}: error in the term file: {type(exc).__name__}: {exc}") from exc
    out = dict(catalogue if catalogue is not None else CATALOGUE)
    found = [v for v in vars(module).values() if isinstance(v, Term)]
    if not found:
        raise UserError(f"{p}: defines no term (decorate a column function with @term(...))")
    for t in found:
        if t.name in out or t.name == "base":  # a user term never replaces a built-in one
            raise UserError(
                f"{p}: term {t.name!r} has the name of a built-in term; give yours another "
                f"name (@term(name=...)); taken: base, {', '.join(out)}"
            )
        out[t.name] = t
    return out


# ---- model specification --------------------------------------------------------------------
@dataclass(frozen=True)
class ModelTerm:
    """A term applied to some channels: ``term`` on ``sensor`` axes ``axes`` (indices)."""

    term: Term
    sensor: str
    axes: tuple[int, ...]

    @property
    def label(self) -> str:
        """'temperature_bias:gyro:x' style."""
        return f"{self.term.name}:{self.sensor}:{''.join(AXES[a] for a in self.axes)}"

    @property
    def n_params(self) -> int:
        return len(self.term.params) * (1 if self.term.shared else len(self.axes))

    def slots(self) -> list[tuple[int | None, str, str]]:
        """(output axis or None for a shared parameter, name, parameter key) of each of its
        parameters, in the order of its design columns."""
        if self.term.shared:
            names = self.term.param_labels(self.sensor, self.axes[0])
            return [(None, n, k) for n, k in zip(names, self.term.params, strict=True)]
        return [
            (ax, n, self.term.params[q])
            for ax in self.axes
            for q, n in enumerate(self.term.param_labels(self.sensor, ax))
        ]


def parse_model(spec: str, catalogue: Mapping[str, Term] | None = None) -> list[ModelTerm]:
    """``"base,temperature_bias:gyro:x"`` -> model terms. Items ``term[:sensor[:axes]]``;
    ``base`` = bias, scale, misalignment, g_sensitivity. UserError on a bad spec."""
    cat = catalogue if catalogue is not None else CATALOGUE
    items = [s.strip() for s in spec.split(",") if s.strip()]
    if not items:
        raise UserError("empty model spec; e.g. --model base or --model bias,scale")
    out: list[ModelTerm] = []
    for item in items:
        parts = item.split(":")
        if len(parts) > 3:
            raise UserError(f"model item {item!r}: expected term[:sensor[:axes]]")
        name = parts[0]
        is_base = name == "base"
        if not is_base and name not in cat:
            raise UserError(f"unknown term {name!r}; known: base, {', '.join(cat)}")
        for t in [cat[n] for n in BASE] if is_base else [cat[name]]:
            sensors = t.sensors
            if len(parts) > 1 and parts[1]:
                if parts[1] not in SENSORS:
                    raise UserError(f"model item {item!r}: sensor must be accel or gyro")
                if parts[1] not in t.sensors:
                    if is_base:
                        continue  # base:accel -> g_sensitivity has no accel part
                    raise UserError(f"term {name} does not act on the {parts[1]}")
                sensors = (parts[1],)
            axes_txt = parts[2] if len(parts) > 2 and parts[2] else AXES
            if any(c not in AXES for c in axes_txt):
                raise UserError(f"model item {item!r}: axes must be letters of xyz")
            axes = tuple(sorted({AXES.index(c) for c in axes_txt}))
            out.extend(ModelTerm(t, s, axes) for s in sensors)
    return merge_model(out)


def merge_model(terms: Iterable[ModelTerm]) -> list[ModelTerm]:
    """Join the axes of repeated (term, sensor) pairs, keeping first-seen order."""
    order: list[tuple[str, str]] = []
    axes: dict[tuple[str, str], set[int]] = {}
    objs: dict[tuple[str, str], Term] = {}
    for mt in terms:
        key = (mt.term.name, mt.sensor)
        if key not in axes:
            order.append(key)
            axes[key] = set()
            objs[key] = mt.term
        axes[key].update(mt.axes)
    return [ModelTerm(objs[k], k[1], tuple(sorted(axes[k]))) for k in order]


def model_spec(model: Sequence[ModelTerm]) -> str:
    """The spec string of a model (inverse of :func:`parse_model`)."""
    return ",".join(mt.label for mt in model)


def short_spec(model: Sequence[ModelTerm]) -> str:
    """The spec with ``base`` for the whole §2 linear model and ``term:sensor`` for all
    three axes: 'base,temperature_bias:gyro:y' (same model as :func:`model_spec`)."""
    full = {(mt.term.name, mt.sensor): mt.axes for mt in model}
    base = [ModelTerm(CATALOGUE[n], s, (0, 1, 2)) for n in BASE for s in CATALOGUE[n].sensors]
    has_base = all(full.get((b.term.name, b.sensor)) == (0, 1, 2) for b in base)
    items = ["base"] if has_base else []
    for mt in model:
        if has_base and mt.term.name in BASE:
            continue
        axes = "" if mt.axes == (0, 1, 2) else ":" + "".join(AXES[a] for a in mt.axes)
        items.append(f"{mt.term.name}:{mt.sensor}{axes}")
    return ",".join(items)


# ---- noise model ----------------------------------------------------------------------------
@dataclass(frozen=True)
class NoiseModel:
    """How uncertain each row is (see the module docstring).

    ``block_s``: length of the blocks static records are cut into, s (at most ``max_blocks``);
    ``floor``: bias-instability floor per sensor (m/s², °/s): the std of a record's mean bias
    wander between records that its own samples cannot show. Not given: measured from the
    session itself by :func:`repeat_floor` (the same attitude measured again minutes later);
    ``turn_angle_sigma_deg``: the hand's angle error per turn (method.md §4).
    """

    block_s: float = 5.0
    max_blocks: int = 6
    #: per sensor; a sensor not given is measured from the records (:func:`repeat_floor`)
    floor: Mapping[str, float] = field(default_factory=dict)
    turn_angle_sigma_deg: float = TURN_ANGLE_SIGMA_DEG
    max_lag: int = 30


#: a still moment inside a turn record lasts at least this long, s, after :data:`STILL_TRIM_S`
#: is cut at each end (the hand letting go / taking hold)
STILL_MIN_S = 0.1
STILL_TRIM_S = 0.05
#: the floor (:func:`repeat_floor`) compares still moments with static records: it keeps only
#: long, settled ones (a hand letting go rocks the cube for a moment)
FLOOR_MIN_S = 0.2
FLOOR_TRIM_S = 0.15


def still_runs(
    rate_up_dps: np.ndarray,
    t_s: np.ndarray,
    sigma_dps: float,
    *,
    trim_s: float | None = None,
    min_s: float | None = None,
) -> list[tuple[int, int]]:
    """[start, stop) index ranges where the cube rests inside a turn record: the rate about the
    up axis ``rate_up_dps`` (N,) °/s (static bias removed) stays within 4·``sigma_dps`` (the
    gyro's per-sample noise, °/s) of zero; ``trim_s`` (default :data:`STILL_TRIM_S`) s cut at
    each end, at least ``min_s`` (:data:`STILL_MIN_S`) s left (times ``t_s`` (N,) s)."""
    trim = STILL_TRIM_S if trim_s is None else trim_s
    least = STILL_MIN_S if min_s is None else min_s
    still = np.abs(rate_up_dps) < 4.0 * max(sigma_dps, 1e-6)
    out: list[tuple[int, int]] = []
    i, n = 0, len(still)
    while i < n:
        if not still[i]:
            i += 1
            continue
        j = i
        while j < n and still[j]:
            j += 1
        a = int(np.searchsorted(t_s, t_s[i] + trim))
        b = int(np.searchsorted(t_s, t_s[j - 1] - trim, side="right"))
        if b - a >= 4 and t_s[b - 1] - t_s[a] >= least:
            out.append((a, b))
        i = j
    return out


def repeat_floor(
    differences: np.ndarray,
    white_var: np.ndarray,
    channel: np.ndarray | None = None,
    explain: np.ndarray | None = None,
) -> float | None:
    """Bias-instability floor from repeated attitudes: ``differences`` (K,) between two means
    of the same channel in the same attitude measured at different times (a still moment of a
    turn against the static record of that face), ``white_var`` (K,) the variance their white
    noise alone gives the difference. Each record mean wanders by f around the session's
    bias, so E[d²] = w + 2·f²: f² = Σ(d² − w)/(2·dof) (≥ 0), in the channel's unit.

    A bias that follows time or temperature is an effect for the model to find, not noise:
    with ``channel`` (K,) ids and ``explain`` (K, m) the differences of those signals (elapsed
    time, temperature change), each channel's d is first regressed on them (dof = K − the
    columns used). None without any difference left (then nothing measures the floor). A
    floor the differences cannot resolve (f² below its standard error) is given as that
    bound, not as 0."""
    d = np.asarray(differences, dtype=np.float64)
    w = np.asarray(white_var, dtype=np.float64)
    if d.size == 0:
        return None
    ch = np.zeros(d.size, dtype=int) if channel is None else np.asarray(channel)
    x = np.zeros((d.size, 0)) if explain is None else np.asarray(explain, dtype=np.float64)
    resid = d.copy()
    used = 0
    for c in np.unique(ch):
        m = ch == c
        xc = x[m]
        keep = [j for j in range(xc.shape[1]) if np.ptp(xc[:, j]) > 0 or np.any(xc[:, j])]
        if keep and m.sum() > len(keep) + 1:
            beta, _, rank, _ = np.linalg.lstsq(xc[:, keep], d[m], rcond=None)
            resid[m] = d[m] - xc[:, keep] @ beta
            used += int(rank)
    dof = d.size - used
    if dof <= 0:
        return None
    f2 = float(np.sum(resid * resid - w)) / (2.0 * dof)
    # its standard error with no wander (var d² = 2·w²): a floor below it is not resolved by
    # these repeats, and 0 would claim a precision the data do not have — take that bound
    resolved = math.sqrt(float(np.sum(2.0 * w * w))) / (2.0 * dof)
    return math.sqrt(max(f2, resolved))


def _resolution(x: np.ndarray) -> float:
    """Smallest step between distinct values of ``x`` (its quantisation), 0 if constant."""
    u = np.unique(x)
    if len(u) < 2:
        return 0.0
    d = np.diff(u)
    return float(np.min(d[d > 1e-12])) if np.any(d > 1e-12) else 0.0


def integrated_autocorrelation(dev: np.ndarray, max_lag: int) -> float:
    """1 + 2·Σρ_k of the deviations ``dev`` (N,), summed until ρ_k first drops to ≤ 0;
    the variance of a mean of m samples is σ²·τ/m (clipped to 1 … 50)."""
    n = len(dev)
    var = float(dev @ dev) / max(n, 1)
    if n < 4 or var <= 0:
        return 1.0
    tau = 1.0
    for k in range(1, min(max_lag, n // 4) + 1):
        rho = float(dev[k:] @ dev[:-k]) / (n * var)
        if rho <= 0:
            break
        tau += 2.0 * rho
    return float(min(max(tau, 1.0), 50.0))


# ---- dataset: rows, their noise and the whitening ------------------------------------------
@dataclass(frozen=True, eq=False)
class Group:
    """The rows of one record and channel: ``rows`` indices; ``sigma`` = std of their mean
    (static: block-mean average; turn: the integral); ``contrast_sigma`` = std of a block's
    deviation from the record's mean (NaN for one row)."""

    record: int
    sensor: str
    axis: int
    rows: np.ndarray
    sigma: float
    contrast_var: float


@dataclass(frozen=True, eq=False)
class Dataset:
    """Everything the fits need from a session: signals, rows and the whitening.

    Rows (n): ``y`` measured block mean (unit of the channel) or turn integral (°), ``nominal``
    the ideal sensor's value (the aggregated reference input on the channel), ``span`` (n,2)
    within-record time span s. ``whiten`` (n,n): W with W·Cov·Wᵀ = I.
    """

    signals: tuple[RecordSignals, ...]
    row_record: np.ndarray
    row_sensor: np.ndarray  # 0 accel, 1 gyro
    row_axis: np.ndarray
    row_integral: np.ndarray
    span: np.ndarray
    y: np.ndarray
    nominal: np.ndarray
    whiten: np.ndarray
    groups: tuple[Group, ...]
    aggregators: tuple[np.ndarray, ...]  # per record (B, N): block-mean or trapezoid weights
    rows_of: dict[tuple[int, str, int], np.ndarray]
    g: float
    notes: tuple[str, ...] = ()
    #: False: the records carry no power-on time (time = within-record, centred)
    time_known: bool = True
    #: the bias-instability floor of a record mean per sensor (m/s², °/s) this dataset uses
    floor: Mapping[str, float] = field(default_factory=dict)
    #: turns n of each turn record (record name -> n)
    turns_of: Mapping[str, int] = field(default_factory=dict)
    #: (record, sensor, axis) -> its own aggregator where it differs from the record's: the
    #: accelerometer of a turn record is read at the still moments (one row per still moment)
    #: and, on the horizontal axes, in the moving blocks (:mod:`host.modelling.turning`)
    sensor_aggregators: Mapping[tuple[int, str, int], np.ndarray] = field(default_factory=dict)

    @property
    def n_rows(self) -> int:
        return int(self.y.shape[0])

    @functools.cached_property
    def group_means_whitened(self) -> np.ndarray:
        """(n_rows, groups) W⁻ᵀ·a for each group's mean a (:func:`residual_sigmas`), solved
        once per dataset (W does not change between fits)."""
        a = np.zeros((self.n_rows, len(self.groups)))
        for k, gr in enumerate(self.groups):
            a[gr.rows, k] = 1.0 / len(gr.rows)
        return np.asarray(np.linalg.solve(self.whiten.T, a))

    def aggregator(self, record: int, sensor: str, axis: int) -> np.ndarray:
        """(B, N) weights turning record ``record``'s samples into its rows of ``sensor``'s
        channel ``axis``."""
        return self.sensor_aggregators.get((record, sensor, axis), self.aggregators[record])

    def record_name(self, i: int) -> str:
        return self.signals[i].name


def _block_edges(n: int, duration_s: float, noise: NoiseModel) -> list[tuple[int, int]]:
    b = int(max(1, min(noise.max_blocks, round(duration_s / noise.block_s))))
    b = max(1, min(b, n // 8 if n >= 8 else 1))
    edges = np.linspace(0, n, b + 1).round().astype(int)
    return [(int(edges[i]), int(edges[i + 1])) for i in range(b)]


def _runs_of(agg: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) sample ranges of the rows of a still-moment aggregator."""
    out = []
    for row in agg:
        nz = np.flatnonzero(row)
        out.append((int(nz[0]), int(nz[-1]) + 1))
    return out


def turn_heading(t_s: np.ndarray, rate_up_dps: np.ndarray) -> np.ndarray:
    """(N,) the angle turned about the up axis since the record began, ° (trapezoid rule over
    the reference rate ``rate_up_dps`` (N,) °/s at times ``t_s`` (N,) s; method.md §4)."""
    if len(t_s) < 2:
        return np.zeros(len(t_s))
    step = np.diff(t_s) * (rate_up_dps[1:] + rate_up_dps[:-1]) / 2.0
    return np.concatenate([[0.0], np.cumsum(step)])


def _turn_reference(
    rec_gyro: np.ndarray, t_ms: np.ndarray, up: np.ndarray, bias_dps: np.ndarray, want_deg: float
) -> np.ndarray:
    """(N,3) reference rate of a turn: the measured rate about the up axis (static bias
    removed), scaled so that its trapezoid integral is exactly ``want_deg``."""
    raw = (rec_gyro - bias_dps) @ up
    total = float(trapezoid_integral(t_ms, raw))
    if abs(total) < 1e-6:
        return np.zeros((len(t_ms), 3))
    return (raw * (want_deg / total))[:, None] * up[None, :]


def _session_floor(
    signals: Sequence[RecordSignals],
    rec_noise: Mapping[tuple[int, str, int], tuple[float, float]],
    nm: NoiseModel,
) -> tuple[dict[str, float], str]:
    """The floor per sensor (``nm.floor`` where given, else :func:`repeat_floor` over the still
    moments of the turn records against the static record of the same face — every gyro
    channel and the accelerometer on the up axis, whose readings do not depend on the
    heading — and over static records of the same attitude, e.g. a repeated ``x_up_2``, every
    channel) and a note saying where it came from. (A slow effect that differs between the
    two measurements, e.g. a drift, inflates it: a noise file, ``--noise``, does not.)"""
    diffs: dict[str, tuple[list[float], list[float]]] = {s: ([], []) for s in SENSORS}

    for sig in signals:
        if sig.kind != "turn":
            continue
        match = next(
            (j for j, o in enumerate(signals) if o.kind == "static" and np.allclose(o.up, sig.up)),
            None,
        )
        if match is None:
            continue
        ref = signals[match]
        up_axis = int(np.argmax(np.abs(sig.up)))
        sd = math.sqrt(rec_noise[(match, "gyro", up_axis)][0])
        for a, b in still_runs(sig.rate @ sig.up, sig.t_s, sd, trim_s=FLOOR_TRIM_S,
                               min_s=FLOOR_MIN_S):  # fmt: skip
            m = b - a
            # back at the placement heading (a whole number of turns: the record's start and
            # end) every accelerometer axis repeats the static attitude; elsewhere only the up
            # axis does (a plate tilt moves the horizontal ones with the heading)
            turned = float(np.mean(sig.heading_deg[a:b])) if sig.heading_deg is not None else 0.0
            home = abs(turned - 360.0 * round(turned / 360.0)) < 5.0
            for s, axes in (("gyro", (0, 1, 2)), ("accel", (0, 1, 2) if home else (up_axis,))):
                for ax in axes:
                    var, tau = rec_noise[(match, s, ax)]
                    d = float(np.mean(sig.measured(s)[a:b, ax]) - np.mean(ref.measured(s)[:, ax]))
                    diffs[s][0].append(d)
                    diffs[s][1].append(var * min(tau, m) / m + var * tau / len(ref.t_s))

    # static records of the same attitude (the closing check): every channel
    for j, sj in enumerate(signals):
        for i in range(j):
            si = signals[i]
            if not (sj.kind == si.kind == "static" and np.allclose(sj.up, si.up)):
                continue
            for s in SENSORS:
                for ax in range(3):
                    vi, ti = rec_noise[(i, s, ax)]
                    vj, tj = rec_noise[(j, s, ax)]
                    d = float(np.mean(sj.measured(s)[:, ax]) - np.mean(si.measured(s)[:, ax]))
                    diffs[s][0].append(d)
                    diffs[s][1].append(vi * ti / len(si.t_s) + vj * tj / len(sj.t_s))
    out: dict[str, float] = {}
    said: list[str] = []
    for s in SENSORS:
        if s in nm.floor:
            out[s] = float(nm.floor[s])
            said.append(f"{s} {out[s]:.2g} {UNIT[s]} (given)")
            continue
        f = repeat_floor(np.array(diffs[s][0]), np.array(diffs[s][1]))
        out[s] = f if f is not None else 0.0
        said.append(
            f"{s} {out[s]:.2g} {UNIT[s]} from {len(diffs[s][0])} repeated attitudes (still "
            "moments of turns and static records against a static record of the same face)"
            if f is not None
            else f"{s} 0 (no attitude measured twice: only each record's own noise)"
        )
    return out, "noise floor of a record mean: " + "; ".join(said)


def _seating_sigma(
    signals: Sequence[RecordSignals],
    sensor_aggs: Mapping[tuple[int, str, int], np.ndarray],
    groups_raw: Sequence[tuple[int, str, int, list[int], np.ndarray, float]],
    n_still: Mapping[int, int],
) -> tuple[float, str]:
    """How far the cube's attitude at a still moment of a hand turn departs from resting flat,
    as specific force on a horizontal accelerometer, m/s² (and a note; 0 and '' without the
    data). The hand holds or presses the cube between pushes, so each still moment is a new
    seating. Measured from the still moments themselves: per turn and horizontal channel a
    constant (bias, face error, misalignment: all fixed in the body) plus ONE plate tilt for
    the session, g·(t_e·e(ψ) + t_n·n(ψ)) (:func:`plate_tilt`); the scatter beyond each mean's
    white noise, Σ(r² − w)/dof, is the seating variance (method.md §8: repeatability;
    :func:`host.modelling.turning.excess_scatter`)."""
    keys: list[tuple[int, int]] = []
    ys: list[float] = []
    cols_l: list[np.ndarray] = []
    ws: list[float] = []
    for ri, s, ax, _idx, agg, var_tau in groups_raw:
        sig = signals[ri]
        if s != "accel" or sig.kind != "turn" or abs(float(sig.up[ax])) > 0.5:
            continue
        if (ri, "accel", ax) not in sensor_aggs:
            continue
        cols = plate_tilt.columns(sig, "accel", ax) if plate_tilt.columns else None
        assert cols is not None
        for b in range(n_still.get(ri, 0)):
            m = float(np.count_nonzero(agg[b]))
            keys.append((ri, ax))
            ys.append(float(agg[b] @ sig.accel[:, ax]))
            cols_l.append(agg[b] @ cols)
            ws.append(var_tau / m)
    if not ys or len(ys) <= len(set(keys)) + 2:
        return 0.0, ""
    sigma, dof = turning.excess_scatter(np.array(ys), keys, np.array(cols_l), np.array(ws))
    if dof <= 0:
        return 0.0, ""
    return sigma, (
        f"seating of the cube at the still moments of the turns: {sigma:.2g} m/s² on a "
        f"horizontal accelerometer ({1000 * sigma / 9.8:.2g} mrad), from {len(ys)} still "
        f"moments ({dof} dof beyond one plate tilt and a constant per turn and channel)"
    )


def _hand_sigma(
    signals: Sequence[RecordSignals],
    sensor_aggs: Mapping[tuple[int, str, int], np.ndarray],
    n_still: Mapping[int, int],
    white_level: Mapping[tuple[str, int], float],
) -> tuple[tuple[float, float], str]:
    """The hand's scatter on a horizontal accelerometer while the cube turns, m/s²: (of a
    moving block's mean about its turn's level, of that level about the turn's level at rest)
    and a note ('' without moving blocks): beyond a constant per turn and channel, the lever arm
    and the plate tilt, and beyond the sensor's white noise (``white_level`` (sensor, axis) ->
    variance·τ of one sample, from the static records) —
    :func:`host.modelling.turning.hand_scatter`, module docstring there."""
    keys: list[tuple[int, int]] = []
    ys: list[float] = []
    cl: list[np.ndarray] = []
    ws: list[float] = []
    rest: dict[Hashable, tuple[float, float, np.ndarray]] = {}
    for ri, sig in enumerate(signals):
        if sig.kind != "turn":
            continue
        lever: np.ndarray | None = None
        for ax in range(3):
            agg = sensor_aggs.get((ri, "accel", ax))
            if agg is None or n_still.get(ri, 0) >= agg.shape[0]:
                continue
            moving = agg[n_still[ri] :]
            counts = np.count_nonzero(moving, axis=1).astype(float)
            tilt0 = plate_tilt.columns(sig, "accel", ax) if plate_tilt.columns else None
            assert tilt0 is not None
            if n_still[ri]:
                # the same turn and channel at rest: the still moments' mean
                still = agg[: n_still[ri]]
                m_still = still.mean(axis=0)
                n_s = float(np.count_nonzero(still))
                rest[(ri, ax)] = (
                    float(m_still @ sig.accel[:, ax]),
                    white_level.get(("accel", ax), 0.0) / n_s,
                    np.concatenate([np.zeros(3), m_still @ tilt0]),
                )
            if lever is None:
                lever = turning.lever_arm_matrix(sig.t_s, sig.rate)
            tilt = plate_tilt.columns(sig, "accel", ax) if plate_tilt.columns else None
            assert tilt is not None
            keys.extend([(ri, ax)] * len(moving))
            ys.extend((moving @ sig.accel[:, ax]).tolist())
            cl.extend(moving @ np.column_stack([lever[:, ax, :], tilt]))
            ws.extend((white_level.get(("accel", ax), 0.0) / counts).tolist())
    if not ys:
        return (0.0, 0.0), ""
    block, level, dof = turning.hand_scatter(np.array(ys), keys, np.array(cl), np.array(ws),
                                             rest)  # fmt: skip
    return (block, level), (
        f"the hand while the cube turns: {block:.2g} m/s² on a horizontal accelerometer's "
        f"block mean ({turning.BLOCK_S:g} s) about the turn's level, from {len(ys)} moving "
        f"blocks ({dof} dof beyond a constant per turn and channel, the lever arm and the "
        f"plate tilt); a turn's level while moving departs from its level at rest by {level:.2g}"
    )


def _whiten_exact(
    whiten: np.ndarray,
    record: int,
    sensor: str,
    axis: int,
    idx: Sequence[int],
    cov: np.ndarray,
) -> Group:
    """Whiten the rows ``idx`` of one record and channel exactly when their variances differ
    or they are correlated (still moments and moving blocks of a turn): ``cov`` their
    covariance, W = L⁻¹ with L its Cholesky factor, written into ``whiten``; -> the
    :class:`Group`."""
    b = len(idx)
    if not np.all(np.diag(cov) > 0.0):
        raise UserError(
            f"record {record}: accel {'xyz'[axis]} reads the same value in every sample while "
            "turning (noise-free data): give a floor, e.g. --floor accel=1e-4,gyro=1e-3"
        )
    w = np.linalg.inv(np.linalg.cholesky(cov))
    whiten[np.ix_(list(idx), list(idx))] = w
    v_mean = float(np.sum(cov)) / b**2
    return Group(
        record, sensor, axis, np.array(idx), math.sqrt(v_mean), float(np.mean(np.diag(cov)))
    )


def build_dataset(
    session: Session,
    *,
    noise: NoiseModel | None = None,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
    turns: int | None = None,
    earth_rate: bool = False,
    moving: bool = True,
) -> Dataset:
    """Check the records (:func:`host.calibration.build_observations`) and build the rows.

    ``earth_rate``: the reference rate includes the vertical Earth rate (as
    :func:`~host.calibration.build_observations`). ``moving``: the accelerometer's block means
    over the turning parts of the turn records are rows too (:mod:`host.modelling.turning`;
    the lever arm shows only there). UserError when there is nothing to fit (no static
    records, bad records).
    """
    nm = noise or NoiseModel()
    if not session.records:
        raise UserError("no records to fit")
    g = local_gravity(latitude_deg, height_m)
    stats = {n: record_stats(r) for n, r in session.records.items()}
    obs, notes = build_observations(
        session, g, turns=turns, stats=stats, earth_rate=earth_rate, latitude_deg=latitude_deg
    )
    obs_of = {o.record: o for o in obs}
    names = [n for n in session.records if n in obs_of]
    has_power = all("power_on_s" in session.records[n].meta for n in names)
    if not has_power:
        notes.append(
            "records carry no power-on time (meta power_on_s): time terms see only the time "
            "within each record (centred on its middle)"
        )
    # preliminary static gyro bias + g-sensitivity (per channel), for the turn reference rate
    statics = [n for n in names if obs_of[n].kind in ("static", "rate")]
    xs = np.array([np.concatenate([obs_of[n].force, [1.0]]) for n in statics])
    ys = np.array([stats[n].gyro_mean - obs_of[n].rate for n in statics])
    pre, *_ = np.linalg.lstsq(xs, ys, rcond=None)
    # per-sample gyro noise (°/s) per axis: finds the still moments inside the turns
    gyro_sd = np.median([stats[n].gyro_std for n in statics], axis=0)

    temp_mean = float(np.mean([float(np.mean(session.records[n].temp)) for n in names]))
    signals: list[RecordSignals] = []
    aggs: list[np.ndarray] = []
    rows: dict[str, list[float]] = {k: [] for k in ("rec", "sen", "ax", "int", "t0", "t1")}
    y_list: list[float] = []
    nom_list: list[float] = []
    groups_raw: list[tuple[int, str, int, list[int], np.ndarray, float]] = []
    # white-noise levels from the statics (for the turns): sensor -> axis -> (var, tau) lists
    static_noise: dict[tuple[str, int], list[tuple[float, float]]] = {}
    rec_noise: dict[tuple[int, str, int], tuple[float, float]] = {}
    sensor_aggs: dict[tuple[int, str, int], np.ndarray] = {}
    still_spans: dict[int, list[tuple[float, float]]] = {}
    #: turn record -> how many of its accelerometer rows are still moments (the rest: moving)
    n_still: dict[int, int] = {}

    for ri, name in enumerate(names):
        rec = session.records[name]
        o = obs_of[name]
        n = len(rec)
        t_rel = (rec.t_ms - rec.t_ms[0]) / 1000.0
        # without power-on times only the variation within a record is known: centre it
        t0 = float(rec.meta.get("power_on_s", "0") or 0.0) if has_power else -float(t_rel.mean())
        force = np.tile(g * o.up, (n, 1)) if o.kind != "rate" else np.tile(g * rec.up, (n, 1))
        if o.kind == "turn":
            bias_up = pre[:3].T @ o.up + pre[3]
            want = float(o.rate @ o.up)
            rate = _turn_reference(rec.gyro, rec.t_ms, o.up, bias_up, want)
            heading: np.ndarray | None = turn_heading(t_rel, rate @ o.up)
        else:  # rate table; statics: zero, or the vertical Earth rate
            rate = np.tile(o.rate, (n, 1))
            heading = None
        sig = RecordSignals(
            name=name, kind=o.kind, t_s=t0 + t_rel, temp_c=rec.temp.copy(), force=force,
            rate=rate, accel=rec.accel, gyro=rec.gyro, g=g, up=o.up, temp_mean_c=temp_mean,
            heading_deg=heading,
        )  # fmt: skip
        signals.append(sig)
        if o.kind == "turn":
            w = np.zeros(n)
            dt = np.diff(rec.t_ms) / 1000.0
            w[1:] += dt / 2
            w[:-1] += dt / 2
            agg = w[None, :]
            spans = [(0.0, float(t_rel[-1]))]
            sensors: tuple[str, ...] = ("gyro",)
            # the accelerometer at the still moments: gravity seen at several headings
            up_k = int(np.argmax(np.abs(o.up)))
            runs = still_runs(rate @ o.up, t_rel, float(gyro_sd[up_k]))
            # ... and while it turns (the lever arm): block means of the moving parts
            blocks = (
                turning.moving_blocks(rate @ o.up, t_rel, float(gyro_sd[up_k])) if moving else []
            )
            if runs or blocks:
                acc_agg = np.zeros((len(runs) + len(blocks), n))
                for b, (a, e) in enumerate([*runs, *blocks]):
                    acc_agg[b, a:e] = 1.0 / (e - a)
                for ax in range(3):
                    # the up channel reads no lever arm, only the hand pressing and tilting
                    # the cube (g·(1 − cos θ), one-signed): its moving blocks are left out
                    horizontal = abs(float(o.up[ax])) < 0.5
                    sensor_aggs[(ri, "accel", ax)] = acc_agg if horizontal else acc_agg[: len(runs)]
                still_spans[ri] = [
                    (float(t_rel[a]), float(t_rel[e - 1])) for a, e in [*runs, *blocks]
                ]
                n_still[ri] = len(runs)
                sensors = ("accel", "gyro")
        else:
            edges = _block_edges(n, float(t_rel[-1]) if n else 0.0, nm)
            agg = np.zeros((len(edges), n))
            for b, (a, e) in enumerate(edges):
                agg[b, a:e] = 1.0 / (e - a)
            spans = [(float(t_rel[a]), float(t_rel[e - 1])) for a, e in edges]
            sensors = SENSORS
        aggs.append(agg)
        for s in sensors:
            meas = sig.measured(s)
            ref = sig.reference(s)
            still = o.kind == "turn" and s == "accel"
            for ax in range(3):
                s_agg = sensor_aggs[(ri, s, ax)] if still else agg
                s_spans = still_spans[ri] if still else spans
                if not s_agg.shape[0]:
                    continue
                idx = list(range(len(y_list), len(y_list) + s_agg.shape[0]))
                yv = s_agg @ meas[:, ax]
                nv = s_agg @ ref[:, ax]
                y_list.extend(yv.tolist())
                nom_list.extend(nv.tolist())
                for b in range(s_agg.shape[0]):
                    rows["rec"].append(ri)
                    rows["sen"].append(SENSORS.index(s))
                    rows["ax"].append(ax)
                    rows["int"].append(o.kind == "turn" and not still)
                    rows["t0"].append(s_spans[b][0])
                    rows["t1"].append(s_spans[b][1])
                if o.kind == "turn" and not still:
                    groups_raw.append((ri, s, ax, idx, agg, 0.0))
                    continue
                if still:
                    # white noise of a still moment's mean from its own samples (NaN without
                    # still moments: the static records' level is taken below)
                    ns = n_still[ri]
                    if ns == 0:
                        groups_raw.append((ri, s, ax, idx, s_agg, math.nan))
                        continue
                    dev = np.concatenate(
                        [meas[a:e, ax] - meas[a:e, ax].mean() for a, e in _runs_of(s_agg[:ns])]
                    )
                    dof = max(len(dev) - ns, 1)
                    var = max(float(dev @ dev) / dof, _resolution(meas[:, ax]) ** 2 / 12.0)
                    tau = integrated_autocorrelation(dev, nm.max_lag)
                    groups_raw.append((ri, s, ax, idx, s_agg, var * tau))
                    continue
                # white noise of a block mean from the record's own samples
                dev = np.concatenate([meas[a:e, ax] - meas[a:e, ax].mean() for a, e in edges])
                dof = max(len(dev) - len(edges), 1)
                var = max(float(dev @ dev) / dof, _resolution(meas[:, ax]) ** 2 / 12.0)
                tau = integrated_autocorrelation(dev, nm.max_lag)
                static_noise.setdefault((s, ax), []).append((var, tau))
                rec_noise[(ri, s, ax)] = (var, tau)
                groups_raw.append((ri, s, ax, idx, agg, var * tau))

    floors, floor_note = _session_floor(signals, rec_noise, nm)
    notes.append(floor_note)
    seat, seat_note = _seating_sigma(signals, sensor_aggs, groups_raw, n_still)
    if seat_note:
        notes.append(seat_note)
    white_level = {k: float(np.mean([v * t for v, t in lv])) for k, lv in static_noise.items()}
    hand, hand_note = _hand_sigma(signals, sensor_aggs, n_still, white_level)
    if hand_note:
        notes.append(hand_note)
    n_rows = len(y_list)
    whiten = np.zeros((n_rows, n_rows))
    groups: list[Group] = []
    # within-record wander: pooled excess scatter of block means over their prediction
    excess: dict[tuple[str, int], list[float]] = {}
    y_arr = np.array(y_list)
    for _ri, s, ax, idx, agg, var_tau in groups_raw:
        if len(idx) >= 2 and signals[_ri].kind != "turn":
            m = agg.sum(axis=1)  # ones
            counts = np.count_nonzero(agg, axis=1)
            v_b = var_tau / counts * m
            yb = y_arr[idx]
            chi = float(np.sum((yb - yb.mean()) ** 2 / v_b))
            excess.setdefault((s, ax), []).extend([chi, len(idx) - 1])
    inflate = {k: max(1.0, sum(v[0::2]) / max(sum(v[1::2]), 1.0)) for k, v in excess.items()}
    for ri, s, ax, idx, agg, var_tau in groups_raw:
        floor = floors[s]
        if signals[ri].kind == "turn" and s == "gyro":
            w = agg[0]
            levels = static_noise.get((s, ax), [(0.0, 1.0)])
            v_white = float(np.mean([v * t for v, t in levels]))
            T = float(w.sum())
            var = v_white * float(w @ w) + (floor * T) ** 2 + nm.turn_angle_sigma_deg**2
            whiten[idx[0], idx[0]] = 1.0 / math.sqrt(var)
            groups.append(Group(ri, s, ax, np.array(idx), math.sqrt(var), math.nan))
            continue
        counts = np.count_nonzero(agg, axis=1).astype(float)
        level = white_level.get((s, ax), 0.0)
        v_blocks = (var_tau if math.isfinite(var_tau) else level) / counts  # each block mean
        horizontal = abs(float(signals[ri].up[ax])) < 0.5
        ns = n_still.get(ri, len(idx)) if signals[ri].kind == "turn" else len(idx)
        if signals[ri].kind == "turn" and horizontal:
            v_blocks[:ns] = v_blocks[:ns] + seat**2  # a horizontal channel at a still moment
        if ns < len(idx):
            # moving blocks: the sensor's white noise (the static records' level) + the hand
            v_blocks[ns:] = level / counts[ns:]
            cov = np.diag(v_blocks) + floor**2
            cov[ns:, ns:] += turning.hand_covariance(hand[0], hand[1], len(idx) - ns)
            groups.append(_whiten_exact(whiten, ri, s, ax, idx, cov))
            continue
        b = len(idx)
        v_mean = float(np.sum(v_blocks)) / b**2 + floor**2
        if not v_mean > 0.0:
            raise UserError(
                f"{signals[ri].name}: {s} {'xyz'[ax]} reads the same value in every sample "
                "(noise-free data, or a stuck sensor): the fit weighs each record by its "
                "noise; give a floor, e.g. --floor accel=1e-4,gyro=1e-3 (m/s², °/s), or check "
                "the sensor"
            )
        whiten[idx[0], idx] = (1.0 / b) / math.sqrt(v_mean)
        turn = signals[ri].kind == "turn"  # still moments: their spread is the signal
        v_c = float(np.mean(v_blocks)) * (1.0 if turn else inflate.get((s, ax), 1.0))
        if not v_c > 0.0:  # noise-free samples (with a given floor): the only scale there is
            v_c = v_mean
        if b >= 2:
            # orthonormal Helmert contrasts of the b blocks
            for k in range(1, b):
                h = np.zeros(b)
                h[:k] = 1.0
                h[k] = -float(k)
                h /= np.linalg.norm(h)
                whiten[idx[k], idx] = h / math.sqrt(v_c)
        groups.append(Group(ri, s, ax, np.array(idx), math.sqrt(v_mean), v_c))
    rows_of: dict[tuple[int, str, int], np.ndarray] = {}
    for gr in groups:
        rows_of[(gr.record, gr.sensor, gr.axis)] = gr.rows
    return Dataset(
        signals=tuple(signals),
        row_record=np.array(rows["rec"], dtype=int),
        row_sensor=np.array(rows["sen"], dtype=int),
        row_axis=np.array(rows["ax"], dtype=int),
        row_integral=np.array(rows["int"], dtype=bool),
        span=np.column_stack([rows["t0"], rows["t1"]]),
        y=y_arr,
        nominal=np.array(nom_list),
        whiten=whiten,
        groups=tuple(groups),
        aggregators=tuple(aggs),
        rows_of=rows_of,
        g=g,
        notes=tuple(notes),
        time_known=has_power,
        floor=floors,
        turns_of={o.record: o.turns for o in obs if o.kind == "turn" and o.turns is not None},
        sensor_aggregators=sensor_aggs,
    )


# ---- design matrix --------------------------------------------------------------------------
def aggregate(agg: np.ndarray, per_sample: np.ndarray) -> np.ndarray:
    """Rows of one record from per-sample values: ``agg`` (B,N) @ ``per_sample`` (N,…), with
    round-off (below 1e-9 of the largest per-sample value) set to exactly 0."""
    out = agg @ per_sample
    scale = float(np.max(np.abs(per_sample))) if per_sample.size else 0.0
    out[np.abs(out) < 1e-9 * scale] = 0.0
    return np.asarray(out)


def _call_term(t: Term, what: str, sig: RecordSignals, fn: Callable[[], Any]) -> np.ndarray:
    """Call a term's function (user code, maybe): any exception or a non-finite value becomes
    one UserError naming the term, the function and the record."""
    try:
        x = np.asarray(fn(), dtype=np.float64)
    except UserError:
        raise
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - a term's error: one line
        raise UserError(
            f"term {t.name}: {what}() raised {type(exc).__name__}: {exc} (record {sig.name})"
        ) from None
    if not np.all(np.isfinite(x)):
        raise UserError(
            f"term {t.name}: {what}() returned {int(np.count_nonzero(~np.isfinite(x)))} "
            f"non-finite values (NaN or inf) for record {sig.name}; it must give finite numbers"
        )
    return x


def _regressors(t: Term, sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    columns = t.columns
    assert columns is not None
    x = _call_term(t, "columns", sig, lambda: columns(sig, sensor, axis))
    if x.ndim == 1:
        x = x[:, None]
    if x.shape != (len(sig.t_s), len(t.params)):
        raise UserError(
            f"term {t.name}: columns() returned shape {x.shape}, expected "
            f"({len(sig.t_s)}, {len(t.params)})"
        )
    return x


def term_columns(
    ds: Dataset, mt: ModelTerm, theta: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Design columns (n_rows, n_params) of a model term and its offset (n_rows,).

    Linear terms: offset 0. Nonlinear terms: the Jacobian at ``theta`` (parameters in the
    order axis-major) and offset value(θ) − J·θ, so that value ≈ offset + J·θ'. A shared
    term (:attr:`Term.shared`, linear only) has one set of k columns: each channel's rows hold
    that channel's regressors.
    """
    k = len(mt.term.params)
    if mt.term.shared:
        if mt.term.nonlinear:
            raise UserError(f"term {mt.term.name}: a shared term must be linear (columns())")
        cols = np.zeros((ds.n_rows, k))
        for ax in mt.axes:
            for ri, sig in enumerate(ds.signals):
                rows = ds.rows_of.get((ri, mt.sensor, ax))
                if rows is not None:
                    cols[rows] = aggregate(
                        ds.aggregator(ri, mt.sensor, ax), _regressors(mt.term, sig, mt.sensor, ax)
                    )
        return cols, np.zeros(ds.n_rows)
    cols = np.zeros((ds.n_rows, k * len(mt.axes)))
    offset = np.zeros(ds.n_rows)
    th = (
        np.tile(np.array(mt.term.initial), len(mt.axes))
        if theta is None and mt.term.nonlinear
        else theta
    )
    for j, ax in enumerate(mt.axes):
        for ri, sig in enumerate(ds.signals):
            rows = ds.rows_of.get((ri, mt.sensor, ax))
            if rows is None:
                continue
            agg = ds.aggregator(ri, mt.sensor, ax)
            if not mt.term.nonlinear:
                cols[rows, j * k : (j + 1) * k] = aggregate(
                    agg, _regressors(mt.term, sig, mt.sensor, ax)
                )
                continue
            value = mt.term.value
            assert value is not None and th is not None
            p = np.asarray(th[j * k : (j + 1) * k], dtype=np.float64)

            def at(
                pp: np.ndarray,
                sig: RecordSignals = sig,
                ax: int = ax,
                value: ValueFn = value,
            ) -> np.ndarray:
                return _call_term(mt.term, "value", sig, lambda: value(sig, mt.sensor, ax, pp))

            v0 = at(p)
            jac = np.zeros((len(sig.t_s), k))
            for q in range(k):
                h = 1e-6 * max(1.0, abs(p[q]))
                dp = np.zeros(k)
                dp[q] = h
                jac[:, q] = (at(p + dp) - at(p - dp)) / (2 * h)
            cols[rows, j * k : (j + 1) * k] = agg @ jac
            offset[rows] = agg @ (v0 - jac @ p)
    return cols, offset


# ---- statistics (pure numpy) ----------------------------------------------------------------
def chi2_sf(x: float, dof: float) -> float:
    """P(χ²_dof > x): the regularised upper incomplete gamma Q(dof/2, x/2)."""
    if dof <= 0 or not math.isfinite(x):
        return float("nan") if not math.isfinite(x) else 1.0
    if x <= 0:
        return 1.0
    a, z = 0.5 * dof, 0.5 * x
    gln = math.lgamma(a)
    if z < a + 1.0:  # series for P
        term_, total, ap = 1.0 / a, 1.0 / a, a
        for _ in range(1000):
            ap += 1.0
            term_ *= z / ap
            total += term_
            if abs(term_) < abs(total) * 1e-15:
                break
        return float(max(0.0, 1.0 - total * math.exp(-z + a * math.log(z) - gln)))
    # continued fraction for Q (Lentz)
    tiny = 1e-300
    b = z + 1.0 - a
    c = 1.0 / tiny
    d = 1.0 / b
    h = d
    for i in range(1, 1000):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = tiny if abs(d) < tiny else d
        c = b + an / c
        c = tiny if abs(c) < tiny else c
        d = 1.0 / d
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < 1e-15:
            break
    return float(min(1.0, math.exp(-z + a * math.log(z) - gln) * h))


def chi2_isf(p: float, dof: float) -> float:
    """x with P(χ²_dof > x) = p (bisection on :func:`chi2_sf`)."""
    lo, hi = 0.0, max(10.0, dof * 10.0)
    while chi2_sf(hi, dof) > p:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if chi2_sf(mid, dof) > p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


# ---- the fit --------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Parameter:
    """One fitted parameter: §2-style ``name``, owning model-term label, value, 1-σ std error
    (NaN value: the records do not determine it), unit; ``sensor``, ``axis`` (x/y/z, the output
    channel) and ``key`` (the term's own parameter name, e.g. ``per_C``)."""

    name: str
    term: str
    value: float
    stderr: float
    unit: str
    sensor: str = ""
    axis: str = ""
    key: str = ""

    @property
    def term_name(self) -> str:
        """The catalogue name of the owning term ('temperature_bias')."""
        return self.term.split(":")[0]


#: the χ² test of a channel rejects the model at this level: its standard errors are scaled
ALPHA_FIT = 0.01


def stderr_scale(chi2: float, dof: int) -> float:
    """The project's one uncertainty policy: standard errors come from the noise model; when a
    channel's fit is poor (χ² p < :data:`ALPHA_FIT` and χ² > dof) they are multiplied by
    √(χ²/dof) (the Birge ratio) and the report says so. 1.0 otherwise (and with no dof)."""
    if dof <= 0 or not math.isfinite(chi2) or chi2 <= dof:
        return 1.0
    return math.sqrt(chi2 / dof) if chi2_sf(chi2, dof) < ALPHA_FIT else 1.0


@dataclass(frozen=True, eq=False)
class Combination:
    """A combination of undetermined parameters that the records DO determine:
    Σ coefficient·parameter = value ± stderr (unit of the first parameter)."""

    terms: tuple[tuple[float, str], ...]  # (coefficient, parameter name)
    value: float
    stderr: float
    unit: str

    def describe(self) -> str:
        """'A0x + 9.815·Axx = 0.6021 ± 0.0003 m/s²'."""
        parts: list[str] = []
        for i, (c, n) in enumerate(self.terms):
            sign = "−" if c < 0 else "+"
            mag = abs(c)
            coef = "" if abs(mag - 1.0) < 1e-9 else f"{mag:.4g}·"
            parts.append((("−" if c < 0 else "") if i == 0 else f" {sign} ") + coef + n)
        return f"{''.join(parts)} = {self.value:.6g} ± {self.stderr:.2g} {self.unit}".strip()


@dataclass(frozen=True, eq=False)
class ChannelFit:
    """Fit statistics of one output channel (the channels are independent problems).

    ``dof`` = rows − determined parameters; ``dof_records`` = record/channel values −
    parameters (the between-record test: 0 means the model is not tested at all, verdict
    ``untestable``); ``se_scale``: :func:`stderr_scale`; ``combinations``: what the records
    determine of the undetermined parameters."""

    sensor: str
    axis: str
    chi2: float
    dof: int
    dof_records: int
    se_scale: float
    combinations: tuple[Combination, ...] = ()

    @property
    def channel(self) -> str:
        return f"{self.sensor} {self.axis}"

    @property
    def testable(self) -> bool:
        return self.dof_records > 0


@dataclass(frozen=True, eq=False)
class GroupResidual:
    """Measured vs model for one record and channel (mean over the record, or turn integral).

    ``measured``/``model``/``residual`` in the channel's unit (°/s, m/s²) or ° for turn
    integrals; ``sigma`` the standard error of the measurement; ``z`` = residual / its own
    standard deviation under the model (:func:`residual_sigmas`: the measurement's σ less what
    the fit absorbed), so that z is N(0, 1) when the model is right; NaN when the model fits
    this value exactly (a parameter of its own: nothing is left to test)."""

    record: str
    kind: str
    sensor: str
    axis: str
    measured: float
    model: float
    residual: float
    sigma: float
    z: float
    unit: str

    @property
    def channel(self) -> str:
        return f"{self.sensor} {self.axis}"


@dataclass(frozen=True, eq=False)
class SpanResidual:
    """A block of a static record that departs from its own record's mean residual."""

    record: str
    sensor: str
    axis: str
    t0_s: float
    t1_s: float
    residual: float
    z: float
    unit: str


@dataclass(frozen=True, eq=False)
class Fit:
    """Result of :func:`fit_model` (see :class:`Dataset` for the rows)."""

    model: tuple[ModelTerm, ...]
    parameters: tuple[Parameter, ...]
    predicted: np.ndarray  # (n_rows,)
    residual: np.ndarray  # (n_rows,)
    white_residual: np.ndarray  # W·residual
    basis: np.ndarray  # orthonormal basis of the whitened determined columns
    chi2: float
    dof: int
    n_params: int
    groups: tuple[GroupResidual, ...]
    spans: tuple[SpanResidual, ...]
    undetermined: tuple[str, ...]
    channels: tuple[ChannelFit, ...] = ()

    @property
    def untestable(self) -> tuple[str, ...]:
        """Channels whose record values leave no degrees of freedom ('accel x', …)."""
        return tuple(c.channel for c in self.channels if not c.testable)

    @property
    def scaled(self) -> tuple[ChannelFit, ...]:
        """Channels whose standard errors were scaled (:func:`stderr_scale`)."""
        return tuple(c for c in self.channels if c.se_scale != 1.0)

    def uncertainty_note(self) -> str:
        """The one sentence saying how the standard errors were treated ('' if unscaled)."""
        if not self.scaled:
            return ""
        parts = ", ".join(f"{c.channel} ×{c.se_scale:.2g}" for c in self.scaled)
        return (
            f"poor fit (χ² p < {ALPHA_FIT:g}): standard errors scaled by √(χ²/dof) on {parts}; "
            "the model does not explain these channels"
        )

    @property
    def rms_z(self) -> float:
        """RMS of the record/channel z values (the compare table; values the model fits
        exactly are left out): ≈ 1 when the model explains the data to the noise."""
        z = np.array([g.z for g in self.groups if math.isfinite(g.z)])
        return float(np.sqrt(np.mean(z**2))) if len(z) else float("nan")

    @property
    def chi2_p(self) -> float:
        """P(χ² this large | the model and the noise model are right)."""
        return chi2_sf(self.chi2, self.dof)

    @property
    def bic(self) -> float:
        """χ² + p·ln(n) (known noise variance)."""
        return self.chi2 + self.n_params * math.log(max(len(self.residual), 2))

    def parameter(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)


def design(ds: Dataset, model: Sequence[ModelTerm], thetas: Sequence[np.ndarray | None] = ()) -> (
    tuple[np.ndarray, np.ndarray, list[tuple[int, int]]]
):  # fmt: skip
    """(X (n_rows, P), offset (n_rows,), per model term (start, stop) columns)."""
    blocks: list[np.ndarray] = []
    offset = np.zeros(ds.n_rows)
    spans: list[tuple[int, int]] = []
    col = 0
    for i, mt in enumerate(model):
        th = thetas[i] if i < len(thetas) else None
        c, off = term_columns(ds, mt, th)
        blocks.append(c)
        offset += off
        spans.append((col, col + c.shape[1]))
        col += c.shape[1]
    x = np.column_stack(blocks) if blocks else np.zeros((ds.n_rows, 0))
    return x, offset, spans


def select_columns(xw: np.ndarray, tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Greedy Gram-Schmidt: (mask of columns independent of the earlier ones, orthonormal
    basis (n, r) of their span)."""
    n, p = xw.shape
    q = np.zeros((n, 0))
    keep = np.zeros(p, dtype=bool)
    for j in range(p):
        v = xw[:, j]
        norm = float(np.linalg.norm(v))
        if norm == 0.0:
            continue
        r = v - q @ (q.T @ v)
        r = r - q @ (q.T @ r)
        rn = float(np.linalg.norm(r))
        if rn > tol * norm and rn > 1e-300:
            keep[j] = True
            q = np.column_stack([q, r / rn])
    return keep, q


def fit_model(ds: Dataset, model: Sequence[ModelTerm], max_iter: int = 20) -> Fit:
    """Weighted least squares of ``model`` over all rows of ``ds`` (one problem, all channels).

    Parameters the records cannot determine are reported NaN (and listed in ``undetermined``).
    Nonlinear terms: Gauss-Newton iterations until the parameters settle.
    """
    model = tuple(model)
    thetas: list[np.ndarray | None] = [
        np.tile(np.array(mt.term.initial), len(mt.axes)) if mt.term.nonlinear else None
        for mt in model
    ]
    w = ds.whiten
    iters = max_iter if any(mt.term.nonlinear for mt in model) else 1
    for _ in range(iters):
        x, offset, spans = design(ds, model, thetas)
        xw = w @ x
        yw = w @ (ds.y - ds.nominal - offset)
        keep, basis = select_columns(xw)
        theta = np.full(x.shape[1], np.nan)
        cov = np.zeros((x.shape[1], x.shape[1]))
        if keep.any():
            sol, *_ = np.linalg.lstsq(xw[:, keep], yw, rcond=None)
            theta[keep] = sol
            cov[np.ix_(keep, keep)] = np.linalg.pinv(xw[:, keep].T @ xw[:, keep])
        moved = 0.0
        for i, mt in enumerate(model):
            if mt.term.nonlinear:
                a, b = spans[i]
                old = thetas[i]
                assert old is not None
                new = np.where(np.isfinite(theta[a:b]), theta[a:b], old)
                moved = max(moved, float(np.max(np.abs(new - old) / (1e-12 + np.abs(new)))))
                thetas[i] = new
        if moved < 1e-8:
            break
    th0 = np.nan_to_num(theta)
    predicted = ds.nominal + offset + x @ th0
    resid = ds.y - predicted
    wres = w @ resid
    chi2 = float(wres @ wres)
    n_par = int(keep.sum())
    # who owns each column: (name, unit, channel, term label, sensor, axis, key)
    # (axis -1: a shared parameter of all the sensor's channels)
    owners: list[tuple[str, str, tuple[str, int], str, str]] = []
    for mt in model:
        units = dict(zip(mt.term.params, mt.term.param_units(mt.sensor), strict=True))
        for ax, name, key in mt.slots():
            owners.append((name, units[key], (mt.sensor, -1 if ax is None else ax), mt.label, key))
    channels, estimable = _channel_fits(ds, x, xw, wres, th0, cov, owners)
    scale_of = {(c.sensor, AXES.index(c.axis)): c.se_scale for c in channels}
    for chf in channels:  # a shared parameter: the largest scale of its sensor's channels
        scale_of[(chf.sensor, -1)] = max(scale_of.get((chf.sensor, -1), 1.0), chf.se_scale)
    params: list[Parameter] = []
    undetermined: list[str] = []
    for c, (name, unit, ch, label, key) in enumerate(owners):
        ok = bool(keep[c] and estimable[c])
        se = math.sqrt(max(float(cov[c, c]), 0.0)) * scale_of.get(ch, 1.0) if ok else math.nan
        params.append(
            Parameter(name, label, float(theta[c]) if ok else math.nan, se, unit,
                      ch[0], AXES[ch[1]] if ch[1] >= 0 else "", key)
        )  # fmt: skip
        if not ok:
            undetermined.append(name)
    groups, spans_out = _residual_tables(ds, predicted, resid, basis)
    return Fit(
        model=model, parameters=tuple(params), predicted=predicted, residual=resid,
        white_residual=wres, basis=basis, chi2=chi2, dof=ds.n_rows - n_par, n_params=n_par,
        groups=groups, spans=spans_out, undetermined=tuple(undetermined),
        channels=tuple(channels),
    )  # fmt: skip


def residual_sigmas(ds: Dataset, basis: np.ndarray) -> np.ndarray:
    """Standard deviation of each group's mean residual (ds.groups order) when the model is
    right: the measurement's σ less what the fit absorbed. Cov(r) = W⁻¹(I − QQᵀ)W⁻ᵀ with Q the
    orthonormal basis of the whitened design, so var(aᵀr) = ‖W⁻ᵀa‖² − ‖QᵀW⁻ᵀa‖²; 0 where the
    model has a parameter for that value alone (it is fitted exactly)."""
    v = ds.group_means_whitened
    var = np.sum(v * v, axis=0)
    if basis.shape[1]:
        var = var - np.sum((basis.T @ v) ** 2, axis=0)
    return np.sqrt(np.maximum(var, 0.0))


def _rref(m: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Reduced row echelon form of ``m`` (rows independent), leading coefficients 1."""
    a = np.array(m, dtype=np.float64)
    r = 0
    for col in range(a.shape[1]):
        if r >= a.shape[0]:
            break
        piv = r + int(np.argmax(np.abs(a[r:, col])))
        if abs(a[piv, col]) < tol:
            continue
        a[[r, piv]] = a[[piv, r]]
        a[r] /= a[r, col]
        for i in range(a.shape[0]):
            if i != r:
                a[i] -= a[i, col] * a[r]
        r += 1
    return a[:r]


def _channel_fits(
    ds: Dataset,
    x: np.ndarray,
    xw: np.ndarray,
    wres: np.ndarray,
    theta: np.ndarray,
    cov: np.ndarray,
    owners: Sequence[tuple[str, str, tuple[str, int], str, str]],
) -> tuple[list[ChannelFit], np.ndarray]:
    """Per output channel: χ², dof, record-level dof, the standard-error scale, which columns
    the records determine individually (a parameter is determined when its unit vector lies in
    the row space of the channel's design) and the combinations they do determine."""
    estimable = np.zeros(len(owners), dtype=bool)
    out: list[ChannelFit] = []
    for s_i, sensor in enumerate(SENSORS):
        for ax in range(3):
            rows = np.flatnonzero((ds.row_sensor == s_i) & (ds.row_axis == ax))
            if not len(rows):
                continue
            cols = np.array(
                [c for c, o in enumerate(owners) if o[2] in ((sensor, ax), (sensor, -1))],
                dtype=int,
            )
            xc = xw[np.ix_(rows, cols)] if len(cols) else np.zeros((len(rows), 0))
            norms = np.linalg.norm(xc, axis=0)
            live = norms > 0
            rank, null = 0, np.zeros((len(cols), 0))
            if live.any():
                xn = xc[:, live] / norms[live]
                _, sv, vt = np.linalg.svd(xn, full_matrices=True)
                rank = int(np.sum(sv > 1e-9 * sv[0])) if len(sv) else 0
                null = np.zeros((len(cols), vt.shape[0] - rank))
                null[live] = vt[rank:].T / norms[live, None]  # back to parameter units
            for j, c in enumerate(cols):
                estimable[c] = (
                    estimable[c]
                    or bool(live[j])
                    and (null.shape[1] == 0 or float(np.linalg.norm(null[j] * norms[j])) < 1e-6)
                )
            # record-level design: one row per record/channel value (mean of its rows)
            grs = [g for g in ds.groups if g.sensor == sensor and g.axis == ax]
            rank_g = 0
            if len(cols) and grs:
                xg = np.array([x[np.ix_(g.rows, cols)].mean(axis=0) for g in grs])
                gn = np.linalg.norm(xg, axis=0)
                rank_g = int(np.linalg.matrix_rank(xg[:, gn > 0] / gn[gn > 0], tol=1e-9))
            chi2 = float(wres[rows] @ wres[rows])
            dof = len(rows) - rank
            scale = stderr_scale(chi2, dof)
            combos = (
                _combinations(cols, estimable, null, norms, theta, cov * scale**2, owners)
                if null.shape[1]
                else ()
            )
            out.append(ChannelFit(sensor, AXES[ax], chi2, dof, len(grs) - rank_g, scale, combos))
    if any(o[2][1] < 0 for o in owners):
        # shared parameters couple the channels: what all rows together determine
        estimable = _estimable(xw)
    return out, estimable


def _estimable(xw: np.ndarray) -> np.ndarray:
    """(P,) which columns of the whitened design ``xw`` (n, P) the rows determine: the
    parameter's unit vector lies in the row space (it has no part in the null space)."""
    norms = np.linalg.norm(xw, axis=0)
    live = norms > 0
    out = np.zeros(xw.shape[1], dtype=bool)
    if not live.any():
        return out
    _, sv, vt = np.linalg.svd(xw[:, live] / norms[live], full_matrices=True)
    rank = int(np.sum(sv > 1e-9 * sv[0])) if len(sv) else 0
    null = vt[rank:].T
    idx = np.flatnonzero(live)
    for j, c in enumerate(idx):
        out[c] = null.shape[1] == 0 or float(np.linalg.norm(null[j])) < 1e-6
    return out


def _combinations(
    cols: np.ndarray,
    estimable: np.ndarray,
    null: np.ndarray,
    norms: np.ndarray,
    theta: np.ndarray,
    cov: np.ndarray,
    owners: Sequence[tuple[str, str, tuple[str, int], str, str]],
) -> tuple[Combination, ...]:
    """Combinations c·θ of the undetermined parameters of one channel that the records
    determine: c supported on them with cᵀ·N = 0 (N the null space of the design)."""
    und = [j for j, c in enumerate(cols) if not estimable[c] and norms[j] > 0]
    if not und:
        return ()
    # in normalised coordinates (columns of unit norm) for a well-scaled null space
    ns = null[und] * norms[und, None]
    _, sv, vt = np.linalg.svd(ns.T, full_matrices=True)
    r = int(np.sum(sv > 1e-9 * max(float(sv[0]), 1e-300))) if len(sv) else 0
    basis = vt[r:]
    if not len(basis):
        return ()
    out: list[Combination] = []
    for row in _rref(basis * norms[und][None, :]):
        coef = row / row[np.flatnonzero(np.abs(row) > 1e-12)[0]]
        idx = [cols[und[k]] for k in range(len(und))]
        terms = tuple((float(coef[k]), owners[idx[k]][0]) for k in range(len(und))
                      if abs(coef[k]) > 1e-9)  # fmt: skip
        full = np.zeros(len(theta))
        for k in range(len(und)):
            full[idx[k]] = coef[k]
        value = float(full @ theta)
        se = math.sqrt(max(float(full @ cov @ full), 0.0))
        unit = owners[idx[next(k for k in range(len(und)) if abs(coef[k]) > 1e-9)]][1]
        out.append(Combination(terms, value, se, unit))
    return tuple(out)


def _residual_tables(
    ds: Dataset, predicted: np.ndarray, resid: np.ndarray, basis: np.ndarray
) -> tuple[tuple[GroupResidual, ...], tuple[SpanResidual, ...]]:
    out: list[GroupResidual] = []
    spans: list[SpanResidual] = []
    sd_res = residual_sigmas(ds, basis)
    for k, gr in enumerate(ds.groups):
        sig = ds.signals[gr.record]
        turn = sig.kind == "turn" and gr.sensor == "gyro"  # an integral, °
        unit = "°" if turn else UNIT[gr.sensor]
        r = float(np.mean(resid[gr.rows]))
        sd = float(sd_res[k])
        out.append(
            GroupResidual(
                record=sig.name, kind=sig.kind, sensor=gr.sensor, axis=AXES[gr.axis],
                measured=float(np.mean(ds.y[gr.rows])), model=float(np.mean(predicted[gr.rows])),
                residual=r, sigma=gr.sigma, z=r / sd if sd > 1e-3 * gr.sigma else math.nan,
                unit=unit,
            )
        )  # fmt: skip
        b = len(gr.rows)
        if b >= 2 and math.isfinite(gr.contrast_var):
            sd = math.sqrt(gr.contrast_var * (1.0 - 1.0 / b))
            for row in gr.rows:
                d = float(resid[row]) - r
                spans.append(
                    SpanResidual(sig.name, gr.sensor, AXES[gr.axis], float(ds.span[row, 0]),
                                 float(ds.span[row, 1]), d, d / sd, unit)
                )  # fmt: skip
    return tuple(out), tuple(spans)


def load_dataset(
    directory: str | Path,
    *,
    noise: NoiseModel | None = None,
    latitude_deg: float = DEFAULT_LATITUDE_DEG,
    height_m: float = DEFAULT_HEIGHT_M,
    serial: str | None = None,
) -> Dataset:
    """Read the session in ``directory`` (:func:`host.records.read_session`) and build it."""
    from host.session.directory import read_session

    session = read_session(directory, serial)
    return build_dataset(session, noise=noise, latitude_deg=latitude_deg, height_m=height_m)


def session_from_records(records: Mapping[str, object], serial: str = "SIM") -> Session:
    """A :class:`Session` of in-memory records (e.g. :func:`host.sim.simulate_session`)."""
    from host.session.records import Record

    recs = {k: v for k, v in records.items() if isinstance(v, Record)}
    return Session(serial=serial, records=recs)


# ---- held-out prediction ----------------------------------------------------------------------
@dataclass(frozen=True)
class Prediction:
    """Leave-one-record-out prediction error of a model (:func:`leave_one_out`): each record
    is predicted by the model fitted to all the others; ``rms_z`` = RMS over the predicted
    record/channel values of (measured − predicted)/σ, σ² = the measurement's variance + the
    prediction's; ``n`` values predicted, ``skipped`` records none of whose values the others
    can predict (a value needing a parameter only its own record determines is left out)."""

    rms_z: float
    n: int
    skipped: tuple[str, ...]


def _thetas_of(fit: Fit) -> list[np.ndarray | None]:
    """Per model term, its fitted parameters (for nonlinear terms; None for linear ones)."""
    out: list[np.ndarray | None] = []
    for mt in fit.model:
        if not mt.term.nonlinear:
            out.append(None)
            continue
        vals = [p.value for p in fit.parameters if p.term == mt.label]
        out.append(np.nan_to_num(np.array(vals, dtype=np.float64)))
    return out


def leave_one_out(ds: Dataset, fit: Fit) -> Prediction:
    """Predict every record from the fit of ``fit.model`` to the other records (the design is
    linearised at ``fit``'s parameters for nonlinear terms). A term that only fits noise makes
    this prediction error larger, where χ² always falls (method.md §8: accuracy on attitudes
    not used in the fit)."""
    x, offset, _ = design(ds, fit.model, _thetas_of(fit))
    w = ds.whiten
    y = ds.y - ds.nominal - offset
    zs: list[float] = []
    skipped: list[str] = []
    for ri, sig in enumerate(ds.signals):
        out_rows = ds.row_record == ri
        keep_rows = ~out_rows
        xw = w[np.ix_(keep_rows, keep_rows)] @ x[keep_rows]
        yw = w[np.ix_(keep_rows, keep_rows)] @ y[keep_rows]
        keep, _ = select_columns(xw)
        cols = np.flatnonzero(keep)
        norms = np.linalg.norm(xw, axis=0)
        live = norms > 0
        if not len(cols):
            skipped.append(sig.name)
            continue
        sol, *_ = np.linalg.lstsq(xw[:, cols], yw, rcond=None)
        cov = np.linalg.pinv(xw[:, cols].T @ xw[:, cols])
        _, sv, vt = np.linalg.svd(xw[:, live] / norms[live], full_matrices=True)
        rank = int(np.sum(sv > 1e-9 * sv[0])) if len(sv) else 0
        null = vt[rank:].T  # null space of the others' design, normalised coordinates
        theta = np.zeros(x.shape[1])
        theta[cols] = sol
        rows_z: list[float] = []
        for gr in ds.groups:
            if gr.record != ri:
                continue
            a = x[gr.rows].mean(axis=0)
            an = a[live] / norms[live]
            if np.any(a[~live] != 0.0) or float(np.linalg.norm(an @ null)) > 1e-6 * max(
                float(np.linalg.norm(an)), 1e-300
            ):
                continue  # the others do not determine what this value needs
            r = float(np.mean(y[gr.rows]) - a @ theta)
            var = gr.sigma**2 + float(a[cols] @ cov @ a[cols])
            rows_z.append(r / math.sqrt(var))
        if rows_z:
            zs.extend(rows_z)
        else:
            skipped.append(sig.name)
    z = np.array(zs)
    return Prediction(float(np.sqrt(np.mean(z**2))) if len(z) else math.nan, len(z),
                      tuple(skipped))  # fmt: skip
