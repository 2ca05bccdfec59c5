"""What the terms see of a record: its reference signals (:class:`RecordSignals`: reference
specific force, reference rate, chip temperature, time since power-on, heading) beside the
measured outputs, made from the record and its observation (:func:`record_signals`), and the
names of the sensors, axes and units."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from host.model.turn_angle import angle_free, turn_reference
from host.session.observations import Observation
from host.session.records import Record

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
    None: it did not turn, 0). ``placement_deg``: the record's placement heading on the plate
    at its first sample, ° (its header's ``placement_heading_deg``; None: not recorded).
    ``accel_matrix`` (3, 3): how the accelerometer reads a specific force (scale and
    misalignment, from the static records before the fit; None: as the identity) — what the
    turning force ω̇×r + ω×(ω×r) passes through (:func:`host.model.turning.sensed_lever_matrix`)
    and a face's lean g·θ. ``gyro_scale`` (3,): how each gyro reads a rate along its own axis,
    1 + scale, from the turns before the fit (None: 1) — what a face's lean θ·ω passes through.
    ``tilt_matrix`` (3, 3): how the accelerometer reads the plate's tilt of gravity: the
    static records' matrix with the plate's tilt at their recorded headings taken out first,
    or without them its columns from the turns' circle centres
    (:func:`host.model.plate.tilt_matrices`; None: only its diagonal, the scales, is known
    that well — a tilt at unknown headings reads as misalignment in the statics' matrix).
    ``heading_tilt`` (2,) rad: on a turn record whose ``placement_deg`` was read from its
    rests' circle (not recorded), the plate's tilt (east, north) the circles show — the fit
    carries a correction of that heading as an unknown of the record, linearised there (None:
    the heading is recorded, or it is the frame's origin).
    ``pose_frame``: no record of the session has a set attitude (poses only), so the frame is
    the accelerometer's own by convention (:data:`host.model.poses.FRAME_FIXED`). A pose's
    ``up`` is the first estimate of its attitude (:func:`host.model.poses.attitudes`).
    ``angle_column`` (N, 3): on a turn record that starts or ends in motion (its angle is not
    ±360·n but an unknown of the fit, :data:`host.model.catalogue.scale`), what each gyro
    channel reads per degree of that angle, (°/s)/°: the measured rate less the statics' bias
    over the angle the reference rate turns (None: the turn's angle is known).
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
    placement_deg: float | None = None
    accel_matrix: np.ndarray | None = None
    gyro_scale: np.ndarray | None = None
    heading_tilt: np.ndarray | None = None
    tilt_matrix: np.ndarray | None = None
    pose_frame: bool = False
    angle_column: np.ndarray | None = None

    def reference(self, sensor: str) -> np.ndarray:
        """(N,3) the true input of ``sensor``: specific force m/s² or rate °/s."""
        return self.force if sensor == "accel" else self.rate

    def measured(self, sensor: str) -> np.ndarray:
        """(N,3) the measured output of ``sensor``."""
        return self.accel if sensor == "accel" else self.gyro

    @property
    def lever_matrix(self) -> np.ndarray | None:
        """(3, 3) how the accelerometer reads a specific force other than gravity (the turning
        force of :func:`host.model.turning.sensed_lever_matrix`): :attr:`tilt_matrix` where it
        is known (on a tilted plate the statics' misalignments hold the tilt at their unknown
        headings: 15 mrad of a 1° tilt mixes 0.7 mm of a 5 cm offset's other components into
        each), else :attr:`accel_matrix`."""
        return self.tilt_matrix if self.tilt_matrix is not None else self.accel_matrix

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

    @property
    def plate_heading(self) -> np.ndarray:
        """(N,) the cube's heading on the plate, rad: the placement heading (zero when the
        record does not say) plus the angle
        turned since the first sample."""
        return self.heading + np.radians(self.placement_deg or 0.0)


def true_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges of the runs of True in the boolean ``mask`` (N,)."""
    m = np.asarray(mask, dtype=bool)
    edges = np.flatnonzero(np.diff(np.concatenate([[False], m, [False]]).astype(np.int8)))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def turn_heading(t_s: np.ndarray, rate_up_dps: np.ndarray) -> np.ndarray:
    """(N,) the angle turned about the up axis since the record began, ° (trapezoid rule over
    the reference rate ``rate_up_dps`` (N,) °/s at times ``t_s`` (N,) s; method.md §4)."""
    if len(t_s) < 2:
        return np.zeros(len(t_s))
    step = np.diff(t_s) * (rate_up_dps[1:] + rate_up_dps[:-1]) / 2.0
    return np.concatenate([[0.0], np.cumsum(step)])


def record_signals(
    rec: Record,
    o: Observation,
    g: float,
    t0: float,
    t_rel: np.ndarray,
    gyro_bias: np.ndarray,
    temp_mean_c: float,
    accel_matrix: np.ndarray | None = None,
    gyro_scale: np.ndarray | None = None,
    turn_reads: Mapping[int, np.ndarray] | None = None,
) -> RecordSignals:
    """The reference signals of one record (observation ``o``): gravity ``g`` m/s² along its up
    direction, the reference rate (a turn: its measured rate about up less the static
    ``gyro_bias`` (4, 3) (g-sensitivity rows, bias), scaled to the known turn; otherwise the
    observation's rate), the time ``t0`` + ``t_rel`` s and the heading; a turn in motion at an
    end, its angle's column (:func:`host.model.turn_angle.angle_free`, ``turn_reads``:
    :func:`host.model.turn_angle.turn_reads`)."""
    n = len(rec)
    force = np.tile(g * o.up, (n, 1)) if o.kind != "rate" else np.tile(g * rec.up, (n, 1))
    angle: np.ndarray | None = None
    if o.kind == "turn":
        bias_up = gyro_bias[:3].T @ o.up + gyro_bias[3]
        want = float(o.rate @ o.up)
        if o.in_motion:  # its angle unknown: the measured one through the gyro's scale
            reads = (turn_reads or {}).get(int(np.argmax(np.abs(o.up))), o.up)
            want, angle = angle_free(rec, o.up, bias_up, gyro_scale, reads)
        rate = turn_reference(rec.gyro, rec.t_ms, o.up, bias_up, want)
        heading: np.ndarray | None = turn_heading(t_rel, rate @ o.up)
    else:  # rate table; statics: zero, or the vertical Earth rate
        rate = np.tile(o.rate, (n, 1))
        heading = None
    return RecordSignals(
        name=o.record, kind=o.kind, t_s=t0 + t_rel, temp_c=rec.temp.copy(), force=force,
        rate=rate, accel=rec.accel, gyro=rec.gyro, g=g, up=o.up, temp_mean_c=temp_mean_c,
        heading_deg=heading, placement_deg=rec.placement_heading_deg,
        accel_matrix=accel_matrix if o.kind in ("turn", "static") else None,
        gyro_scale=gyro_scale if o.kind in ("turn", "static") else None, angle_column=angle,
    )  # fmt: skip
