"""The one optional effect of an independent session: each a small function.

An effect is either a change of the bench's geometry (plate tilt, tilted turn axis, face lean,
lever arm: it sets :class:`~tests.independent.truth.Geometry`) or a sensor effect, a function of
the record's true signals that adds to the outputs. ``EFFECTS`` maps a name to a maker
``(rng) -> Effect``; the effect's ``params`` are its truth (written to the session's truth file).
Sizes are "clear": about 100× the white noise of a 10 s record mean (accel 4.5e-4 m/s², gyro
1.1e-3 °/s) where the issue asks for that.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tests.independent.physics import AXES
from tests.independent.truth import Geometry


@dataclass
class Signals:
    """True inputs of one record, per sample: ``power_on_s`` (N,) s since power-on,
    ``session_s`` (N,) s since the session's first record, ``temp_c`` (N,) °C,
    ``dtemp_c_per_s`` (N,) °C/s, ``force`` (N, 3) m/s², ``rate`` (N, 3) °/s, ``g`` m/s²."""

    power_on_s: np.ndarray
    session_s: np.ndarray
    temp_c: np.ndarray
    dtemp_c_per_s: np.ndarray
    force: np.ndarray
    rate: np.ndarray
    g: float


#: (signals) -> (accel add (N,3) m/s², gyro add (N,3) °/s)
SensorFn = Callable[[Signals], tuple[np.ndarray, np.ndarray]]


@dataclass
class Effect:
    """One effect: ``name``, its truth ``params``, an optional sensor function ``sensor`` and an
    optional ``geometry`` change (applied to the session's Geometry)."""

    name: str
    params: dict[str, Any] = field(default_factory=dict)
    sensor: SensorFn | None = None
    geometry: Callable[[Geometry], None] | None = None
    #: called by the simulator before each record with (name, start, end, end of the record
    #: before it or None), s since the session began: an effect placed in the plan's pauses or
    #: records reads its time from them
    before_record: Callable[[str, float, float, float | None], None] | None = None


def _channel(sensor: str, axis: int, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``values`` (N,) on one channel, zero elsewhere."""
    n = values.shape[0]
    a, g = np.zeros((n, 3)), np.zeros((n, 3))
    (a if sensor == "accel" else g)[:, axis] = values
    return a, g


def _pick(rng: np.random.Generator, k: int = 1) -> list[int]:
    return [int(i) for i in rng.choice(3, size=k, replace=False)]


def _sign(rng: np.random.Generator) -> float:
    return float(rng.choice([-1.0, 1.0]))


# ---- geometry ----------------------------------------------------------------------------
def plate_tilt(rng: np.random.Generator) -> Effect:
    """The plate's normal leans 0.1°–1° toward any room azimuth."""
    tilt = math.radians(rng.uniform(0.1, 1.0))
    az = rng.uniform(0.0, 2 * math.pi)

    def geo(g: Geometry) -> None:
        g.plate_tilt_rad, g.plate_azimuth_rad = tilt, az

    # gravity's up direction in the plate's frame: the plate's normal leans toward az, so up
    # leans the other way (east = along the fence, north = up × east)
    up_e, up_n = -math.sin(tilt) * math.cos(az), -math.sin(tilt) * math.sin(az)
    params = {
        "tilt_rad": tilt,
        "tilt_deg": math.degrees(tilt),
        "normal_azimuth_deg": math.degrees(az),
        "up_east_rad": up_e,
        "up_north_rad": up_n,
    }
    return Effect("plate_tilt", params, geometry=geo)


def _lean_off(k: int, size: float, phi: float) -> np.ndarray:
    """A tilt of ``size`` rad off body axis ``k``, toward azimuth ``phi`` rad in the plane of the
    other two axes (the body vector the turn axis leans by)."""
    others = [i for i in range(3) if i != k]
    lean = np.zeros(3)
    lean[others[0]], lean[others[1]] = size * math.cos(phi), size * math.sin(phi)
    return lean


def turn_axis_tilt(rng: np.random.Generator) -> Effect:
    """The turns about one axis (both ways) are made with the cube seated 2°–5° off its face:
    the turn axis (vertical) and gravity both lean from the nominal up axis in the body."""
    k = _pick(rng)[0]
    size = math.radians(rng.uniform(2.0, 5.0))
    lean = _lean_off(k, size, rng.uniform(0, 2 * math.pi))

    def geo(g: Geometry) -> None:
        g.turn_lean[AXES[k]] = lean

    params = {"axis": AXES[k], "lean_rad": lean.tolist(), "tilt_deg": math.degrees(size)}
    return Effect("turn_axis_tilt", params, geometry=geo)


def one_turn_axis_tilt(rng: np.random.Generator) -> Effect:
    """One turn record alone is made with the cube seated 3°–4° off its face (the other turn
    about the same axis, and every static, seated flat): a hand that pressed one edge."""
    k = _pick(rng)[0]
    record = f"{AXES[k]}_{('ccw', 'cw')[int(rng.integers(0, 2))]}"
    size = math.radians(rng.uniform(3.0, 4.0))
    lean = _lean_off(k, size, rng.uniform(0, 2 * math.pi))

    def geo(g: Geometry) -> None:
        g.record_lean[record] = lean

    params = {"axis": AXES[k], "record": record, "lean_rad": lean.tolist(),
              "tilt_deg": math.degrees(size)}  # fmt: skip
    return Effect("one_turn_axis_tilt", params, geometry=geo)


def one_turn_axis_tilt_tilted_plate(rng: np.random.Generator) -> Effect:
    """:func:`one_turn_axis_tilt` on a plate tilted 1° toward a random azimuth (with headings
    unrecorded, the plate's tilt then bounds where each turn's axis sits)."""
    e = one_turn_axis_tilt(rng)
    tilt, az = math.radians(1.0), float(rng.uniform(0, 2 * math.pi))
    seat = e.geometry
    assert seat is not None

    def geo(g: Geometry) -> None:
        seat(g)
        g.plate_tilt_rad, g.plate_azimuth_rad = tilt, az

    params = {**e.params, "plate_tilt_rad": tilt, "plate_azimuth_rad": az}
    return Effect("one_turn_axis_tilt_tilted_plate", params, geometry=geo)


def face_lean(rng: np.random.Generator) -> Effect:
    """Every face of the fixture leans 1–5 mrad (either sign) toward both other axes."""
    leans: dict[str, np.ndarray] = {}
    for k in range(3):
        for s in "+-":
            v = np.zeros(3)
            for i in range(3):
                if i != k:
                    v[i] = _sign(rng) * rng.uniform(1e-3, 5e-3)
            leans[s + AXES[k]] = v

    def geo(g: Geometry) -> None:
        g.face_lean.update(leans)

    return Effect(
        "face_lean", {"lean_rad": {f: v.tolist() for f, v in leans.items()}}, geometry=geo
    )


def face_pair_lean(rng: np.random.Generator) -> Effect:
    """One pair of opposite fixture faces, ±j, both lean 2–5 mrad the same way toward axis i
    (a fixture sheared along one axis): resting on either, accelerometer i reads +g·lean. On
    the six faces this is what accelerometer i reading c·(f_j/g)² puts there too."""
    i, j = _pick(rng, 2)
    size = _sign(rng) * rng.uniform(2e-3, 5e-3)
    leans = {}
    for s in "+-":
        v = np.zeros(3)
        v[i] = size
        leans[s + AXES[j]] = v

    def geo(g: Geometry) -> None:
        g.face_lean.update(leans)

    p = {"axis": AXES[i], "source": AXES[j], "lean": size,
         "lean_rad": {f: v.tolist() for f, v in leans.items()}}  # fmt: skip
    return Effect("face_pair_lean", p, geometry=geo)


def lever_arm(rng: np.random.Generator) -> Effect:
    """The sensor sits 2–6 cm off the cube's centre along every axis (either sign)."""
    r = np.array([_sign(rng) * rng.uniform(0.02, 0.06) for _ in range(3)])

    def geo(g: Geometry) -> None:
        g.lever_arm_m = r

    return Effect("lever_arm", {"r_m": r.tolist()}, geometry=geo)


def lever_arm_mm(rng: np.random.Generator) -> Effect:
    """The sensor sits 10–50 mm off the cube's centre along every axis (either sign)."""
    r = np.array([_sign(rng) * rng.uniform(0.010, 0.050) for _ in range(3)])

    def geo(g: Geometry) -> None:
        g.lever_arm_m = r

    return Effect("lever_arm", {"r_m": r.tolist()}, geometry=geo)


def plate_tilt_lever_arm(rng: np.random.Generator) -> Effect:
    """Both: the plate tilted 0.1°–1° toward any azimuth (:func:`plate_tilt`) and the sensor
    10–50 mm off the cube's centre (:func:`lever_arm_mm`), from one stream."""
    tilt, arm = plate_tilt(rng), lever_arm_mm(rng)
    tilt_geo, arm_geo = tilt.geometry, arm.geometry
    assert tilt_geo is not None and arm_geo is not None

    def geo(g: Geometry) -> None:
        tilt_geo(g)
        arm_geo(g)

    return Effect("plate_tilt_lever_arm", {**tilt.params, **arm.params}, geometry=geo)


# ---- sensor ------------------------------------------------------------------------------
def bias_step(
    sensor: str, when: tuple[float, float] = (0.4, 0.6)
) -> Callable[[np.random.Generator], Effect]:
    """A bias step (100× the white noise of a record mean, either sign) at a time drawn
    uniformly in ``when`` × 420 s of the session: half-way through by default (the turns), or
    early (0.05–0.35: among the static faces) or late (0.62–0.85: the last turns and the gap
    before the closing x_up_2). It falls inside a record as often as between two."""

    def make(rng: np.random.Generator) -> Effect:
        i = _pick(rng)[0]
        size = _sign(rng) * (0.05 if sensor == "accel" else 0.12)
        at = rng.uniform(*when) * 420.0  # the session lasts about 380 s

        def fn(s: Signals) -> tuple[np.ndarray, np.ndarray]:
            return _channel(sensor, i, np.where(s.session_s >= at, size, 0.0))

        p = {"sensor": sensor, "axis": AXES[i], "step": size, "at_session_s": at}
        return Effect(f"bias_step_{sensor}", p, sensor=fn)

    return make


#: where in the plan a placed step falls: the records it may fall before (in the pause
#: between the record before and that one), or inside ("in:"), one drawn per session
STEP_PLACES: dict[str, tuple[str, ...]] = {
    "pair": ("x_dn", "y_dn", "z_dn"),  # between the two faces of a pair
    "pairs": ("y_up", "z_up"),  # between two pairs
    "to_turns": ("x_ccw",),  # between the last face and the first turn
    "turn_pair": ("x_cw", "y_cw", "z_cw"),  # between the two turns about one axis
    "turns": ("y_ccw", "z_ccw"),  # between the turns about two axes
    "closing": ("x_up_2",),  # before the closing x_up again
    "in_static": tuple(f"in:{a}_{d}" for a in "xyz" for d in ("up", "dn")),
    "in_turn": tuple(f"in:{a}_{d}" for a in "xyz" for d in ("ccw", "cw")),
    "in_first": ("in:x_up",),  # inside the first record: nothing before it
    "in_last": ("in:x_up_2",),  # inside the closing record: nothing after it
    "in_last_turn": ("in:z_cw",),  # inside the last turn (the last record without x_up_2)
}
#: the sizes a placed step is drawn from (uniform, either sign): m/s², °/s
STEP_SIZES = {"accel": (0.02, 0.1), "gyro": (0.05, 0.5)}


def _step_channel(rng: np.random.Generator, place: str, where: str) -> int:
    """The channel a placed step falls on: in a pause between records about two axes, the axis
    of either (the plan's order lines up with it there: the split pair's own axis, the pair or
    turns measured just before or after); inside a record, its axis half the time; else any."""
    order = [*(f"{a}_{d}" for a in "xyz" for d in ("up", "dn")),
             *(f"{a}_{d}" for a in "xyz" for d in ("ccw", "cw")), "x_up_2"]  # fmt: skip
    rec = where.removeprefix("in:")
    if place in ("pair", "pairs", "turn_pair", "turns"):
        before = order[order.index(rec) - 1]
        return AXES.index(str(rng.choice([before[0], rec[0]])))
    if where.startswith("in:") and rng.uniform() < 0.5:
        return AXES.index(rec[0])
    return _pick(rng)[0]


def bias_step_at(sensor: str, place: str) -> Callable[[np.random.Generator], Effect]:
    """A bias step of 0.02–0.1 m/s² or 0.05–0.5 °/s (either sign) placed in the plan
    (:data:`STEP_PLACES`): in a pause, at 20–80 % of it; inside a record, at 15–85 % of its
    length; on the channel :func:`_step_channel` draws (truth: ``at_session_s``, ``place``,
    ``record``: the record it falls
    before or in)."""

    def make(rng: np.random.Generator) -> Effect:
        lo, hi = STEP_SIZES[sensor]
        size = _sign(rng) * float(rng.uniform(lo, hi))
        k = int(rng.integers(0, len(STEP_PLACES[place])))
        where = STEP_PLACES[place][k]
        i = _step_channel(rng, place, where)
        frac = float(rng.uniform(0.15, 0.85) if where.startswith("in:") else rng.uniform(0.2, 0.8))
        p: dict[str, Any] = {"sensor": sensor, "axis": AXES[i], "step": size,
                             "at_session_s": math.inf, "place": place,
                             "record": where.removeprefix("in:")}  # fmt: skip

        def locate(name: str, start: float, end: float, prev_end: float | None) -> None:
            if where == f"in:{name}":
                p["at_session_s"] = start + frac * (end - start)
            elif where == name and prev_end is not None:
                p["at_session_s"] = prev_end + frac * (start - prev_end)

        def fn(s: Signals) -> tuple[np.ndarray, np.ndarray]:
            return _channel(sensor, i, np.where(s.session_s >= p["at_session_s"], size, 0.0))

        return Effect(f"bias_step_{sensor}_at_{place}", p, sensor=fn, before_record=locate)

    return make


def bias_two_steps(sensor: str) -> Callable[[np.random.Generator], Effect]:
    """Two bias steps on one channel (each 100× the white noise of a record mean, each of
    either sign): the first at a time drawn uniformly in 0.08–0.45 × 420 s of the session, the
    second in 0.55–0.85 (truth: ``step``, ``at_session_s`` the first; ``step_2``,
    ``at_session_s_2`` the second)."""

    def make(rng: np.random.Generator) -> Effect:
        i = _pick(rng)[0]
        big = 0.05 if sensor == "accel" else 0.12
        sizes = (_sign(rng) * big, _sign(rng) * big)
        at = (rng.uniform(0.08, 0.45) * 420.0, rng.uniform(0.55, 0.85) * 420.0)

        def fn(s: Signals) -> tuple[np.ndarray, np.ndarray]:
            v = sizes[0] * (s.session_s >= at[0]) + sizes[1] * (s.session_s >= at[1])
            return _channel(sensor, i, v.astype(float))

        p = {"sensor": sensor, "axis": AXES[i], "step": sizes[0], "at_session_s": at[0],
             "step_2": sizes[1], "at_session_s_2": at[1]}  # fmt: skip
        return Effect(f"bias_two_steps_{sensor}", p, sensor=fn)

    return make


def bias_drift(sensor: str) -> Callable[[np.random.Generator], Effect]:
    """A bias linear in time since power-on, d·hours (catalogue: time_drift)."""

    def make(rng: np.random.Generator) -> Effect:
        i = _pick(rng)[0]
        per_h = _sign(rng) * (0.3 if sensor == "accel" else 0.7)

        def fn(s: Signals) -> tuple[np.ndarray, np.ndarray]:
            return _channel(sensor, i, per_h * s.power_on_s / 3600.0)

        p = {"sensor": sensor, "axis": AXES[i], "per_h": per_h}
        return Effect(f"bias_drift_{sensor}", p, sensor=fn)

    return make


def temperature_bias(rng: np.random.Generator) -> Effect:
    """A gyro bias linear in chip temperature, c·(T − 25 °C) (catalogue: temperature_bias)."""
    i = _pick(rng)[0]
    c = _sign(rng) * 0.05

    def fn(s: Signals) -> tuple[np.ndarray, np.ndarray]:
        return _channel("gyro", i, c * (s.temp_c - 25.0))

    return Effect("temperature_bias", {"sensor": "gyro", "axis": AXES[i], "per_C": c}, sensor=fn)


def temperature_bias_accel(per_c: float = 0.003) -> Callable[[np.random.Generator], Effect]:
    """An accelerometer bias linear in chip temperature, c·(T − 25 °C), c = ±``per_c``
    (m/s²)/°C (catalogue: temperature_bias)."""

    def make(rng: np.random.Generator) -> Effect:
        i = _pick(rng)[0]
        c = _sign(rng) * per_c

        def fn(s: Signals) -> tuple[np.ndarray, np.ndarray]:
            return _channel("accel", i, c * (s.temp_c - 25.0))

        p = {"sensor": "accel", "axis": AXES[i], "per_C": c}
        return Effect("temperature_bias_accel", p, sensor=fn)

    return make


def dtdt_bias(rng: np.random.Generator) -> Effect:
    """A gyro bias that follows the rate of change of the chip temperature, c·dT/dt
    (thermal gradients across the die while it warms; off the catalogue)."""
    i = _pick(rng)[0]
    c = _sign(rng) * 25.0  # (°/s)/(°C/s)

    def fn(s: Signals) -> tuple[np.ndarray, np.ndarray]:
        return _channel("gyro", i, c * s.dtemp_c_per_s)

    p = {"sensor": "gyro", "axis": AXES[i], "per_C_per_s": c}
    return Effect("dtdt_bias", p, sensor=fn)


def cross_g2(rng: np.random.Generator) -> Effect:
    """Accelerometer i reads the square of a cross-axis force: += c·(f_j/g)² (off-catalogue)."""
    i, j = _pick(rng, 2)
    c = _sign(rng) * 0.05

    def fn(s: Signals) -> tuple[np.ndarray, np.ndarray]:
        return _channel("accel", i, c * (s.force[:, j] / s.g) ** 2)

    p = {"sensor": "accel", "axis": AXES[i], "source": AXES[j], "c": c}
    return Effect("cross_g2", p, sensor=fn)


def abs_leak(rng: np.random.Generator) -> Effect:
    """Accelerometer i reads the magnitude of a cross-axis force: += c·|f_j|/g
    (a rectifying leak; off-catalogue)."""
    i, j = _pick(rng, 2)
    c = _sign(rng) * 0.05

    def fn(s: Signals) -> tuple[np.ndarray, np.ndarray]:
        return _channel("accel", i, c * np.abs(s.force[:, j]) / s.g)

    p = {"sensor": "accel", "axis": AXES[i], "source": AXES[j], "c": c}
    return Effect("abs_leak", p, sensor=fn)


def gyro_g2(rng: np.random.Generator) -> Effect:
    """Gyro i reads the square of a specific force: += c·(f_j/g)² (off-catalogue)."""
    i, j = _pick(rng, 2)
    c = _sign(rng) * 0.15

    def fn(s: Signals) -> tuple[np.ndarray, np.ndarray]:
        return _channel("gyro", i, c * (s.force[:, j] / s.g) ** 2)

    p = {"sensor": "gyro", "axis": AXES[i], "source": AXES[j], "c": c}
    return Effect("gyro_g2", p, sensor=fn)


def scale_asymmetry(rng: np.random.Generator) -> Effect:
    """Gyro i's scale differs by ``asym`` between positive and negative rates:
    += ½·asym·|ω_i| (catalogue: scale_asymmetry)."""
    i = _pick(rng)[0]
    asym = _sign(rng) * 0.004

    def fn(s: Signals) -> tuple[np.ndarray, np.ndarray]:
        return _channel("gyro", i, 0.5 * asym * np.abs(s.rate[:, i]))

    return Effect("scale_asymmetry", {"sensor": "gyro", "axis": AXES[i], "asym": asym}, sensor=fn)


def scale_nonlinearity(rng: np.random.Generator) -> Effect:
    """Gyro i reads k2·ω_i² more (°/s; catalogue: scale_nonlinearity)."""
    i = _pick(rng)[0]
    k2 = _sign(rng) * 5e-6

    def fn(s: Signals) -> tuple[np.ndarray, np.ndarray]:
        return _channel("gyro", i, k2 * s.rate[:, i] ** 2)

    p = {"sensor": "gyro", "axis": AXES[i], "k2": k2}
    return Effect("scale_nonlinearity", p, sensor=fn)


def none(rng: np.random.Generator) -> Effect:
    """Nothing hidden: the base model is the whole truth."""
    del rng
    return Effect("none")


EFFECTS: dict[str, Callable[[np.random.Generator], Effect]] = {
    "none": none,
    "plate_tilt": plate_tilt,
    "turn_axis_tilt": turn_axis_tilt,
    "one_turn_axis_tilt": one_turn_axis_tilt,
    "one_turn_axis_tilt_tilted_plate": one_turn_axis_tilt_tilted_plate,
    "face_lean": face_lean,
    "face_pair_lean": face_pair_lean,
    "lever_arm": lever_arm,
    "lever_arm_mm": lever_arm_mm,
    "plate_tilt_lever_arm": plate_tilt_lever_arm,
    "bias_step_accel": bias_step("accel"),
    "bias_step_gyro": bias_step("gyro"),
    "bias_step_accel_early": bias_step("accel", (0.05, 0.35)),
    "bias_step_gyro_early": bias_step("gyro", (0.05, 0.35)),
    "bias_step_accel_late": bias_step("accel", (0.62, 0.85)),
    "bias_step_gyro_late": bias_step("gyro", (0.62, 0.85)),
    **{f"bias_step_{s}_at_{w}": bias_step_at(s, w) for s in ("accel", "gyro") for w in STEP_PLACES},
    "bias_two_steps_accel": bias_two_steps("accel"),
    "bias_two_steps_gyro": bias_two_steps("gyro"),
    "bias_drift_accel": bias_drift("accel"),
    "bias_drift_gyro": bias_drift("gyro"),
    "temperature_bias": temperature_bias,
    "temperature_bias_accel": temperature_bias_accel(),
    "temperature_bias_accel_weak": temperature_bias_accel(0.001),
    "temperature_bias_accel_strong": temperature_bias_accel(0.01),
    "dtdt_bias": dtdt_bias,
    "cross_g2": cross_g2,
    "abs_leak": abs_leak,
    "gyro_g2": gyro_g2,
    "scale_asymmetry": scale_asymmetry,
    "scale_nonlinearity": scale_nonlinearity,
}
