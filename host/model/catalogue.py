"""The built-in terms: ``base`` = bias + scale + misalignment + g_sensitivity is the linear
model of method.md §2; the other catalogue terms are the effects §8 says a residual analysis
should look for (temperature, drift, nonlinearity, the fixture's faces, the plate's tilt, the
turn axis, the lever arm), each with the plausible size of its parameters; and the terms a
result carries from a thermal calibration (:data:`CARRIED`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from host.model import plate, poses, turning
from host.model.geometry import plate_axes
from host.model.signals import AXES, RecordSignals
from host.model.terms import OwnUnknowns, Term, Twin, term

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


def _turn_angle(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """A turn's angle, an unknown of the record where it starts or ends in motion (°, the
    correction of the angle its reference rate turns): each gyro channel reads it through the
    measured rate per degree (:attr:`RecordSignals.angle_column`, the scale and the
    cross-axis terms in it)."""
    assert sig.angle_column is not None
    return np.asarray(sig.angle_column)[:, axis : axis + 1]


#: a turn that starts or ends in motion carries its angle: one unknown of its own on the gyro,
#: which trades with the scale about its axis
_TURN_ANGLE = OwnUnknowns(("turn_angle",), ("°",), _turn_angle,
                          owns=lambda sig: sig.angle_column is not None,
                          sensor="gyro")  # fmt: skip


@term(params={"scale": "1"}, needs="inputs of both signs on this axis (±1 g faces; CW and CCW "
      "turns about the axis)", labels=lambda s, i: (f"{_PREFIX[s]}{AXES[i] * 2}",),
      own=_TURN_ANGLE)  # fmt: skip
def scale(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Relative scale-factor error (method.md §2 Axx, Gxx): output = (1 + s)·input.

    A turn record that starts or ends in motion carries its angle as an unknown of its own on
    the gyro (:func:`_turn_angle`): its integral about up reads (1 + s)·angle, so the scale
    about that axis comes from the other records (a turn at rest, a rate table), or is not
    determined."""
    return sig.reference(sensor)[:, axis : axis + 1]


def _mis_labels(sensor: str, axis: int) -> tuple[str, ...]:
    return tuple(f"{_PREFIX[sensor]}{s}" for s, _, _ in _off_diagonal(axis))


def _pose_attitude(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """A pose's attitude, an unknown of the record: gravity's direction moves from the first
    estimate ``up`` by a·e₁ + b·e₂ (rad, :func:`host.model.poses.attitude_basis`), which the
    accelerometer reads as g·(a·e₁ + b·e₂) on its channels."""
    basis = poses.attitude_basis(sig.up)
    return np.tile(sig.g * basis[:, axis], (len(sig.t_s), 1))


#: a pose (a rest at an attitude nobody set) carries its attitude: two angles of its own on the
#: accelerometer, which a rotation of every pose with the sensor's axes trades for misalignment
_POSE_ATTITUDE = OwnUnknowns(("attitude_a", "attitude_b"), ("rad", "rad"), _pose_attitude,
                             owns=lambda sig: sig.kind == "pose", sensor="accel")  # fmt: skip


@term(params={"m1": "rad", "m2": "rad"}, labels=_mis_labels, own=_POSE_ATTITUDE,
      needs="inputs along the other two axes (gravity along them; turns about them)")  # fmt: skip
def misalignment(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Small-angle axis misalignment (method.md §2 Axz, Axy …): the channel also senses the
    input along the other two axes, with the signs of §2.

    Without a record of a set attitude (poses only) the frame is the accelerometer's own:
    the misalignments :data:`host.model.poses.FRAME_FIXED` are zero by that convention (their
    columns are), and each pose carries its attitude as two unknowns of its own
    (:func:`_pose_attitude`)."""
    ref = sig.reference(sensor)
    cols = np.column_stack([sg * ref[:, k] for _, k, sg in _off_diagonal(axis)])
    if sig.pose_frame and sensor == "accel":
        for c, (name, _, _) in enumerate(_off_diagonal(axis)):
            if f"A{name}" in poses.FRAME_FIXED:
                cols[:, c] = 0.0
    return cols


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


def _face_check(signals: Sequence[RecordSignals]) -> str | None:
    """A face error is not told apart from a tilted plate on static records whose heading is
    unknown: there the tilt reads as a lean fixed in the body, of up to the plate's tilt."""
    unknown = [s.name for s in signals if s.kind == "static" and s.placement_deg is None]
    if not unknown:
        return None
    tilt = plate.session_plate(signals)
    if tilt is None or tilt.p_level >= plate.LEVEL_P:
        return None
    return (
        f"the turns' rests show the plate tilted {1e3 * tilt.size:.1f} mrad and "
        f"{len(unknown)} static records carry no placement_heading_deg: on them the tilt "
        f"reads like a face lean of up to {1e3 * tilt.size:.1f} mrad, so a face error cannot "
        "be separated from it (record the headings, or level the plate below 1 mrad)"
    )


def _face_turn(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """The face lean as gyro ``axis`` sees it: a turn at rate ω about the plate's normal, made
    on face ±j leaning θ toward ``axis``, puts θ·ω (°/s per rad) on that gyro, read through
    its scale (:attr:`RecordSignals.gyro_scale`)."""
    face = _face(sig)
    cols = np.zeros((len(sig.t_s), 2))
    if face is not None and sig.kind == "turn":
        seen = 1.0 if sig.gyro_scale is None else float(sig.gyro_scale[axis])
        omega_up = seen * (sig.rate @ sig.up)
        for c, k in enumerate(_other_axes(axis)):
            if face[0] == k:
                cols[:, c] = omega_up
    return cols


# a face's lean is one angle whether the cube rests or turns on it: the gyro reads it too
@term(sensors=("accel",), params={"pair_a": "rad", "pair_b": "rad"}, needs=_FACE_NEEDS,
      check=_face_check, twin=Twin("gyro", _face_turn),
      labels=lambda s, i: tuple(f"face_error.accel.{AXES[i]}.±{AXES[k]}"
                                for k in _other_axes(i)))  # fmt: skip
def face_error(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Fixture faces not square to the sensor's axes put part of gravity on a horizontal axis.

    Resting on face ±j, the cube stands tilted by θ toward axis i and accelerometer i reads
    g·sin θ ≈ g·θ (rad) of gravity that nominally is all on j, through its scale (the static
    records' matrix, :attr:`RecordSignals.accel_matrix`: a 2 % scale on a 5 mrad lean is 4σ
    of a misalignment).

    One angle per channel and face PAIR (the mean of the two opposite faces; their difference
    acts exactly like the misalignment A_ij and is counted there). This is what makes the three
    §3 bias estimates of a channel disagree: the pairs in which the channel is horizontal get
    g·θ added. On the six faces alone it is indistinguishable from a sensor reading the square
    of a cross-axis specific force (k·a_j², identical at ±1 g).

    ONE geometry for resting and turning: the cube turns about the plate's normal, which is the
    face's normal, so the same lean tilts the turn axis in the body and gyro i sees θ·ω of a
    turn made on face ±j (:func:`_face_turn`, the term's gyro twin): the accelerometer's
    statics and turn rests and the gyro's turns read the one angle. The opposite faces'
    difference moves the accelerometer's and the gyro's misalignment alike (a turn of the
    sensor in the cube), so with this term both are stated in the frame of the faces' mean
    normals. A turn made with the cube seated off its face (a lean the static of that face
    does not have) is measured from its rests instead
    (:func:`host.model.turn_axis.resolve_turn_axes`)."""
    face = _face(sig)
    cols = np.zeros((len(sig.t_s), 2))
    seen = 1.0 if sig.accel_matrix is None else float(sig.accel_matrix[axis, axis])
    if face is not None:
        for c, k in enumerate(_other_axes(axis)):
            if face[0] == k:
                cols[:, c] = sig.g * seen
    return cols


def _plate_tilt_all(sig: RecordSignals, sensor: str) -> list[np.ndarray]:
    """:func:`plate_tilt`'s columns (N, 2) of the three channels, from one reading of the
    plate's axes."""
    out = [np.zeros((len(sig.t_s), 2)) for _ in range(3)]
    if sig.kind in ("static", "turn") and sig.placement_deg is not None:
        east, north = _sensed(sig, *plate_axes(sig.up, sig.plate_heading))
        for axis, cols in enumerate(out):
            cols[:, 0] = sig.g * east[:, axis]
            cols[:, 1] = sig.g * north[:, axis]
    return out


def _sensed(sig: RecordSignals, *vectors: np.ndarray) -> tuple[np.ndarray, ...]:
    """Body vectors (N, 3) as the accelerometer reads them: through its scale and misalignment
    (:attr:`RecordSignals.tilt_matrix`, free of the tilt: 1.5 % of a 1° tilt is 0.26 mrad,
    10 mrad of it 0.17, both beyond the tilt's σ), or its scales alone where that matrix is
    not known (the diagonal of :attr:`RecordSignals.accel_matrix`: the statics' misalignments
    hold a tilt at unknown headings, and that error times the tilt is larger than what they
    would add)."""
    if sig.tilt_matrix is not None:
        return tuple(v @ np.asarray(sig.tilt_matrix).T for v in vectors)
    a = sig.accel_matrix
    return tuple(v if a is None else v * np.diag(np.asarray(a)) for v in vectors)


def _heading_unknown(sig: RecordSignals) -> bool:
    """A record on the plate whose placement heading is not recorded: neither recorded nor
    read from its rests (:func:`host.model.plate.resolve_placements`; two unknowns, the tilt
    as it sees it), or read from its rests' circle (one unknown, that heading's correction)."""
    return sig.kind in ("static", "turn") and (
        sig.placement_deg is None or sig.heading_tilt is not None
    )


def _heading_params(sig: RecordSignals) -> tuple[str, ...]:
    """The unknowns of a record whose heading is not recorded (:func:`_heading_unknown`)."""
    return ("heading",) if sig.placement_deg is not None else ("seen_ref", "seen_side")


def _plate_tilt_seen(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """The plate's tilt as one record at an unknown heading ψ sees it: gravity's up leaning
    ``seen_ref`` toward the record's reference axis and ``seen_side`` toward up × reference
    (rad; the session's tilt turned by −ψ, so of the same size). Resting on a face, the
    horizontal accelerometers read g·(seen_ref·e + seen_side·n) with e, n the plate's axes at
    heading 0 turned by the angle turned since the record began."""
    if sig.placement_deg is not None and sig.heading_tilt is not None:
        # a heading read from the rests' circle, ψ₀: its correction dψ (rad) moves the tilt's
        # reading by ∂/∂ψ g·(t_e·e(ψ) + t_n·n(ψ)) = g·(t_n·e − t_e·n) at the circles' tilt
        east, north = _sensed(sig, *plate_axes(sig.up, sig.plate_heading))
        te, tn = (float(v) for v in sig.heading_tilt)
        return sig.g * (tn * east[:, axis] - te * north[:, axis])[:, None]
    east, north = _sensed(sig, *plate_axes(sig.up, sig.heading))
    return sig.g * np.column_stack([east[:, axis], north[:, axis]])


#: a static (or a turn without rests to read) whose heading is not recorded carries its own
#: unknowns: the plate's tilt as seen at that heading (two angles, whose direction against the
#: session's tilt is the heading), so the fit never assumes one; a turn whose heading was read
#: from its rests' circle carries one, the correction of that heading (rad)
_SEEN_TILT = OwnUnknowns(("seen_ref", "seen_side", "heading"), ("rad", "rad", "rad"),
                         _plate_tilt_seen, owns=_heading_unknown,
                         params_of=_heading_params)  # fmt: skip


# the plate's tilt reads all three channels from one computation (``columns_all``)
@term(sensors=("accel",), params={"tilt_east": "rad", "tilt_north": "rad"},
      labels=lambda s, i: ("plate_tilt.east", "plate_tilt.north"),
      columns_all=_plate_tilt_all, own=_SEEN_TILT,
      needs="the accelerometer at several headings on the plate (the still moments inside the "
      "turn records, a quarter turn or more apart), or static attitudes beyond the six faces "
      "(tilt_45_*)")  # fmt: skip
def plate_tilt(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """A base plate that is not level: gravity leans by the same two angles in every record.

    ONE pair of small angles (rad) for the whole session, in the plate's frame: gravity's
    up direction leans ``tilt_east`` toward the ruler (east) and ``tilt_north`` toward
    north = up × east. The plate does not move, so the angles are shared by every record made
    on it and by all three accelerometer channels (:attr:`Term.shared`). Resting on a face, the
    horizontal accelerometers read g·(tilt_east·e + tilt_north·n) (through the accelerometer's
    matrix, :func:`_sensed`), with e, n the plate's axes
    in body coordinates at the record's heading on the plate (its header's
    ``placement_heading_deg`` plus the angle turned, :func:`host.model.geometry.plate_axes`;
    a turn without one gets it from its rests' circle, :func:`host.model.plate.resolve_placements`,
    and carries that heading's correction as an unknown of its own (``heading``, rad, the fit
    linearised at the circles' tilt), so the tilt's azimuth σ counts the circles' scatter;
    a static without one carries the tilt as it sees it as two unknowns of its own, whose
    direction against the session's tilt is its heading: never assumed).

    What tells it from a fixture-face error or a bias: the cube turning on the plate. A face
    error is fixed in the body, a plate tilt is fixed in the room: at heading ψ (turned ψ
    counter-clockwise about up since the placement) the plate's axes in the body are
    e(ψ) = e·cos ψ − n·sin ψ and n(ψ) = n·cos ψ + e·sin ψ, so at the still moments inside a
    turn record the horizontal accelerometers follow g·|tilt|·cos(ψ − ψ₀) while a face error,
    a bias and a misalignment stay put. On the six static faces alone the two angles act like
    accelerometer biases and misalignments (each face is one heading)."""
    return _plate_tilt_all(sig, sensor)[axis]


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


def _lever_arm_all(sig: RecordSignals, sensor: str) -> list[np.ndarray]:
    """:func:`lever_arm`'s columns (N, 3) of the three channels, m/s² per m, from one
    lever-arm matrix of the turn."""
    if sig.kind != "turn":
        return [np.zeros((len(sig.t_s), 3)) for _ in range(3)]
    m = turning.sensed_lever_matrix(sig.t_s, sig.rate, sig.lever_matrix)
    return [m[:, axis, :] for axis in range(3)]


# the lever arm reads all three channels from one turn's matrix (``columns_all``)
@term(sensors=("accel",), params={"x": "m", "y": "m", "z": "m"}, check=_lever_check,
      columns_all=_lever_arm_all,
      labels=lambda s, i: ("lever_arm.x", "lever_arm.y", "lever_arm.z"),
      needs="turns about at least two axes at a brisk rate (≥ 30 °/s; each turn sees the two "
      "components of the offset perpendicular to its axis)")  # fmt: skip
def lever_arm(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """The sensor sits off the turn axis: turning, the accelerometer also reads ω̇×r + ω×(ω×r).

    ONE offset r = (x, y, z) m of the sensor from the cube's centre, in body axes, shared by
    every channel and every turn (:attr:`Term.shared`; geometry and physics in
    :mod:`host.model.turning`): the turns pivot about the vertical through the cube's
    centre, so a turn about up axis k adds the centripetal −ω²·r⊥ (r without its k component)
    and the tangential ω̇·(e_k × r) to the horizontal accelerometers, with ω the calibrated rate
    of the turn (the reference rate: the gyro about up scaled to ±360°·n, method.md §4) in
    rad/s. Read from the moving blocks of the turn records; zero at rest (static records, the
    still moments). The accelerometer reads that force through its scale and misalignment
    (measured on the static records before the fit). 0.12 m/s² at 90 °/s and r = 5 cm."""
    return _lever_arm_all(sig, sensor)[axis]


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
        plate_tilt, lever_arm,
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
    needs="a thermal calibration of the unit: python3 -m host thermal DIR (the warm-up record, "
    "a chamber ramp), then calibrate --thermal SERIAL_thermal.json",
)
def thermal_bias(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Bias change with chip temperature measured by the thermal calibration (``python3 -m host
    thermal``, method.md §8 "fits bias(T)"): Σ_j c_j·(T − T̄)^j about the session's mean chip
    temperature T̄, the order chosen per channel by that fit (coefficients not carried are 0)."""
    d = sig.temp_c - sig.temp_mean_c
    return np.column_stack([d**j for j in range(1, THERMAL_MAX_ORDER + 1)])


@term(
    sensors=("accel",),
    params={"per_C": "1/°C", "per_C2": "1/°C²"},
    needs="a thermal calibration with the axis up and down across the temperature span: "
    "python3 -m host thermal DIR --scale, then calibrate --thermal SERIAL_thermal.json",
)
def thermal_scale(sig: RecordSignals, sensor: str, axis: int) -> np.ndarray:
    """Accelerometer scale change with chip temperature measured by the thermal calibration
    (``python3 -m host thermal``): output += Σ_q s_q·(T − T̄)^q · input along the axis, about
    the session's mean chip temperature T̄ (coefficients not carried are 0)."""
    d = sig.temp_c - sig.temp_mean_c
    f = sig.reference(sensor)[:, axis]
    return np.column_stack([d * f, d * d * f])


#: terms whose values a result carries from a measurement of their own (not fitted to the
#: calibration records, not offered by the workbench); :func:`host.calib.applying.apply`
#: evaluates them like every other term
CARRIED: dict[str, Term] = {t.name: t for t in (thermal_bias, thermal_scale)}
