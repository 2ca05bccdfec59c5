"""The plate's tilt read from the rests of the turns (issue 25), and the placement headings the
records do not carry.

On a level plate gravity stays fixed in body axes while the cube turns about the vertical: a
face error, a bias or a misalignment reads the same at every rest. A plate tilted by θ toward
a room azimuth puts g·θ on the horizontal accelerometers *fixed in the room*, so at the rests
inside a turn record (headings ψ₀ + 0°, 90°, 180°, …) the two horizontal channels draw a
circle of radius g·θ about their constant part. :func:`turn_circle` fits that circle per turn
record: centre (the body-fixed part) and the tilt as a 2-vector in the record's own placement
frame (its reference axis along the fence). Its size needs no heading; its azimuth in the room
needs the record's ``placement_heading_deg``.

:func:`plate_from_rests` combines the turn records: the tilt's size (weighted mean of the
circles, σ widened by their scatter when they disagree), its room azimuth from the records
whose heading is recorded, and — where a record has no heading — the heading that lines its
circle up with the others, as an estimate with its σ (never a convention). With no heading
recorded at all, the azimuth is given relative to the first turn's reference axis.

:func:`resolve_turn_axes`: the axis each turn was made about, from its circle's centre against
the static of the same face; a turn made with the cube seated off its face (a few degrees) is
named, and its reference rate taken along the measured axis so that the gyro cross-axis values
it would fake are corrected.

Units: rad for tilts, m/s² for specific force, degrees for headings (counter-clockwise seen
from above, from the fence to the reference axis).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from host.model.geometry import plate_axes
from host.model.noise import still_runs
from host.model.signals import RecordSignals
from host.model.stats import chi2_sf

#: a rest for the circle: the rate about up below this, °/s (or 4σ of the gyro's noise), kept
#: after :data:`REST_TRIM_S` s cut at each end — a hand pausing between quarter turns
REST_RATE_DPS = 2.0
REST_TRIM_S = 0.03
#: the rests show a tilt when a level plate would draw such circles with less probability
LEVEL_P = 1e-3


@dataclass(frozen=True)
class TurnCircle:
    """The circle one turn record's rests draw. ``tilt`` (2,) rad: gravity's up leaning toward
    (east, north) as seen in the record's frame at heading 0 (its reference axis along the
    fence); ``cov`` (2, 2) its covariance, rad², from the rests' own scatter; ``rms`` m/s²
    the rests' residual about the circle; ``n_rests``; ``placement_deg`` the header's heading
    (None: not recorded)."""

    record: str
    tilt: np.ndarray
    cov: np.ndarray
    rms: float
    n_rests: int
    placement_deg: float | None
    #: (2,) m/s² the circle's centre on the two horizontal channels (x, y, z order without
    #: up): the body-fixed part, gravity along the turn axis; ``centre_var`` (2,) its variance
    centre: np.ndarray = field(default_factory=lambda: np.zeros(2))
    centre_var: np.ndarray = field(default_factory=lambda: np.zeros(2))

    @property
    def size(self) -> float:
        """|tilt|, rad."""
        return float(np.hypot(*self.tilt))

    @property
    def size_sd(self) -> float:
        """σ of |tilt|, rad (along the tilt's direction)."""
        u = self.tilt / max(self.size, 1e-12)
        return float(math.sqrt(max(float(u @ self.cov @ u), 0.0)))


def _rot(deg: float) -> np.ndarray:
    a = math.radians(deg)
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


def turn_circle(
    sig: RecordSignals, runs: Sequence[tuple[int, int]], min_rests: int = 3
) -> TurnCircle | None:
    """The circle of one turn record's rests ``runs`` (sample ranges [a, b) where the cube is
    still), None with fewer than ``min_rests`` rests or rests that do not span two headings
    90° apart (the circle is then not determined)."""
    if sig.kind != "turn" or len(runs) < min_rests:
        return None
    up_k = int(np.argmax(np.abs(sig.up)))
    hor = [k for k in range(3) if k != up_k]
    turned = sig.heading
    # the plate's axes at every rest's mean heading at once (one placement, R headings)
    east, north = plate_axes(sig.up, np.array([float(np.mean(turned[a:b])) for a, b in runs]))
    means = np.array([sig.accel[a:b].mean(axis=0) for a, b in runs])
    # rows rest by rest, the two horizontal channels in turn: (centre one-hot, g·e, g·n)
    x = np.zeros((2 * len(runs), 4))
    y = np.zeros(2 * len(runs))
    for c, k in enumerate(hor):
        x[c::2, c] = 1.0
        x[c::2, 2] = sig.g * east[:, k]
        x[c::2, 3] = sig.g * north[:, k]
        y[c::2] = means[:, k]
    if np.linalg.matrix_rank(x) < 4 or len(y) <= 4:
        return None
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    resid = y - x @ coef
    dof = len(y) - 4
    s2 = float(resid @ resid) / dof
    full = s2 * np.linalg.inv(x.T @ x)
    return TurnCircle(sig.name, coef[2:], full[2:, 2:], math.sqrt(float(resid @ resid) / len(y)),
                      len(runs), sig.placement_deg, coef[:2], np.diag(full)[:2])  # fmt: skip


@dataclass(frozen=True)
class PlateTilt:
    """The plate's tilt from the turns' rests. ``size``/``size_sd`` rad; ``vector`` (2,) rad
    (east, north) of gravity's up in ``frame`` (the fence when any turn record carries its
    heading, else the first turn's reference axis); ``vector_cov`` (2, 2); ``headings``: turn
    record -> (estimated placement heading °, σ °) for those without one in the header;
    ``circles`` the per-record circles."""

    size: float
    size_sd: float
    vector: np.ndarray
    vector_cov: np.ndarray
    frame: str
    circles: tuple[TurnCircle, ...]
    headings: dict[str, tuple[float, float]] = field(default_factory=dict)
    #: probability of circles this large on a level plate (χ² of every circle's tilt against
    #: its covariance, 2 dof per turn)
    p_level: float = 1.0

    @property
    def azimuth_deg(self) -> float:
        """Where the plate leans (gravity's up tilts toward), ° counter-clockwise from the
        frame's east axis."""
        return math.degrees(math.atan2(self.vector[1], self.vector[0])) % 360.0

    def lines(self, g: float, unknown_statics: Sequence[str] = ()) -> list[str]:
        """What a reader is told: the tilt in mrad and degrees with σ, the circles it came from
        (the check to repeat), the headings estimated, and what an unknown heading costs the
        static records ``unknown_statics`` (their horizontal readings, m/s²)."""
        mrad, sd = 1e3 * self.size, 1e3 * self.size_sd
        out = [
            f"plate tilt {mrad:.2f} ± {sd:.2f} mrad ({math.degrees(self.size):.3f}°), leaning "
            f"toward {self.azimuth_deg:.0f}° from {self.frame}, read from the rests of "
            f"{len(self.circles)} turns: the horizontal accelerometers draw a circle of radius "
            f"g·tilt = {g * self.size:.4f} m/s² about the turn axis"
        ]
        for c in self.circles:
            out.append(
                f"  {c.record}: circle radius {g * c.size:.4f} ± {g * c.size_sd:.4f} m/s² "
                f"({1e3 * c.size:.2f} mrad) from {c.n_rests} rests, residual rms {c.rms:.4f} m/s²"
            )
        for name, (deg, dsd) in self.headings.items():
            out.append(
                f"  {name}: no placement_heading_deg in its header; its circle puts it at "
                f"{deg:.0f} ± {dsd:.0f}° (the nearest way a cube sits against a fence: "
                f"{90 * round(deg / 90) % 360:.0f}°)"
            )
        if unknown_statics and self.p_level < LEVEL_P:
            out.append(
                f"  {len(unknown_statics)} static records carry no heading: on each, the tilt "
                f"puts up to {g * self.size:.4f} m/s² on the horizontal accelerometers; "
                "without plate_tilt the bias and misalignment estimates absorb it, with it each "
                "such record carries its heading as an unknown (the tilt as it sees it), so "
                "its horizontal readings no longer inform the biases — level the plate (a tilt "
                "below 1 mrad) or record placement_heading_deg when a tolerance is that tight"
            )
        return out


def plate_from_rests(circles: Sequence[TurnCircle]) -> PlateTilt | None:
    """Combine the turn records' circles (:func:`turn_circle`); None without any."""
    cs = [c for c in circles if np.all(np.isfinite(c.cov)) and c.size_sd > 0]
    if not cs:
        return None
    w = np.array([1.0 / c.size_sd**2 for c in cs])
    sizes = np.array([c.size for c in cs])
    size = float(w @ sizes / w.sum())
    sd = math.sqrt(1.0 / w.sum())
    if len(cs) > 1:  # circles that disagree beyond their σ widen it (Birge ratio)
        chi2 = float(w @ (sizes - size) ** 2) / (len(cs) - 1)
        sd *= math.sqrt(max(chi2, 1.0))
    known = [c for c in cs if c.placement_deg is not None]
    if known:
        frame = "the fence"
        ref = [(_rot(float(c.placement_deg or 0.0)) @ c.tilt, c.cov) for c in known]
    else:
        frame = f"{cs[0].record}'s reference axis (no turn record carries its heading)"
        ref = [(cs[0].tilt, cs[0].cov)]
    info = sum(np.linalg.inv(cv) for _, cv in ref)
    cov = np.linalg.inv(info)
    vec = cov @ sum(np.linalg.inv(cv) @ v for v, cv in ref)
    headings: dict[str, tuple[float, float]] = {}
    ref_angle = math.degrees(math.atan2(vec[1], vec[0]))
    for c in cs:
        if c.placement_deg is None and (known or c is not cs[0]):
            deg = (ref_angle - math.degrees(math.atan2(c.tilt[1], c.tilt[0]))) % 360.0
            headings[c.record] = (deg, math.degrees(c.size_sd / max(c.size, 1e-12)))
    chi2 = sum(float(c.tilt @ np.linalg.solve(c.cov, c.tilt)) for c in cs)
    p = chi2_sf(chi2, 2.0 * len(cs))
    return PlateTilt(size, sd, np.asarray(vec), cov, frame, tuple(cs), headings, p)


def session_plate(signals: Sequence[RecordSignals]) -> PlateTilt | None:
    """The plate's tilt from a dataset's records (:attr:`host.model.dataset.Dataset.signals`):
    the circles of :func:`turn_circles` combined (:func:`plate_from_rests`)."""
    return plate_from_rests(turn_circles(signals))


def turn_circles(signals: Sequence[RecordSignals]) -> list[TurnCircle]:
    """Each turn record's circle (:func:`turn_circle`) from its rests (the reference rate about
    up within 4σ of the static records' gyro noise, at least :data:`REST_RATE_DPS`: a hand's
    short pauses between quarter turns count); none without static records."""
    statics = [s for s in signals if s.kind == "static"]
    if not statics:
        return []
    gyro_sd = np.median([s.gyro.std(axis=0) for s in statics], axis=0)
    circles = []
    for s in signals:
        if s.kind != "turn":
            continue
        up_k = int(np.argmax(np.abs(s.up)))
        sd = max(float(gyro_sd[up_k]), REST_RATE_DPS / 4.0)
        runs = still_runs(s.rate @ s.up, s.t_s - s.t_s[0], sd, trim_s=REST_TRIM_S, min_s=0.1)
        c = turn_circle(s, runs)
        if c is not None:
            circles.append(c)
    return circles


def with_headings(
    circles: Sequence[TurnCircle], signals: Sequence[RecordSignals]
) -> list[TurnCircle]:
    """The circles with the placement heading each record now carries (e.g. after
    :func:`resolve_placements`): a circle is drawn from the rests alone, the heading only
    places it in the room, so they are those :func:`turn_circles` draws from ``signals``."""
    heading = {s.name: s.placement_deg for s in signals}
    return [replace(c, placement_deg=heading[c.record]) for c in circles]


def resolve_placements(
    signals: Sequence[RecordSignals], g: float, plate: PlateTilt | None
) -> tuple[list[RecordSignals], list[str]]:
    """The records with the placement headings their turns' circles give where the header
    gives none (:func:`plate_from_rests`), and the notes that tell the reader the plate's tilt
    (only when the rests show one: a level plate would draw such circles with probability
    below :data:`LEVEL_P`). A turn record without a heading gets the one
    that lines its circle up with the others, and the fit carries a correction of it as an
    unknown of that record (:attr:`RecordSignals.heading_tilt`: its σ is not the circle's
    alone, and the tilt's azimuth σ counts it); with no heading recorded anywhere, the first
    turn's reference axis is the frame (heading 0: the origin of the azimuth, which no
    estimate but the azimuth depends on). A static record without a heading keeps none: one
    heading cannot be read from one rest, so the fit carries it as an unknown of that record
    (:data:`host.model.catalogue.plate_tilt`'s ``seen_ref``/``seen_side``). ``plate``: the
    records' :func:`session_plate`."""
    out = list(signals)
    if plate is None:
        return out, []
    est = {name: deg for name, (deg, _) in plate.headings.items()}
    if not any(c.placement_deg is not None for c in plate.circles):
        est[plate.circles[0].record] = 0.0
    for i, s in enumerate(out):
        if s.kind == "turn" and s.placement_deg is None and s.name in est:
            read = s.name in plate.headings  # read from its circle: an unknown of the fit
            out[i] = replace(s, placement_deg=est[s.name],
                             heading_tilt=np.array(plate.vector) if read else None)  # fmt: skip
    if plate.p_level >= LEVEL_P:
        return out, []
    unknown = [s.name for s in signals if s.kind == "static" and s.placement_deg is None]
    return out, ["; ".join(line.strip() for line in plate.lines(g, unknown))]


def tilt_matrices(signals: Sequence[RecordSignals], plate: PlateTilt | None) -> list[RecordSignals]:
    """The records with :attr:`RecordSignals.tilt_matrix` set when every static record's
    heading is in the plate's frame: the accelerometer's matrix from the statics' means with
    the plate's tilt at each one's heading taken out (f = b + C·g·(up + tilt), least squares);
    Where they are not, the statics' horizontal readings hold the tilt, so the matrix's
    columns come from the turns' circle centres instead (:func:`_matrix_from_centres`).
    Unchanged on a plate the rests do not show tilted."""
    st = [s for s in signals if s.kind == "static"]
    if plate is None or plate.p_level >= LEVEL_P or len(st) < 4:
        return list(signals)
    if plate.frame != "the fence" or any(s.placement_deg is None for s in st):
        m = _matrix_from_centres(signals, plate)
        if m is None:
            return list(signals)
        return [replace(s, tilt_matrix=m) if s.kind in ("static", "turn") else s for s in signals]
    a = np.array([np.concatenate([s.g * s.up, [1.0]]) for s in st])
    if np.linalg.matrix_rank(a) < 4:
        return list(signals)
    ys = []
    for s in st:
        east, north = plate_axes(s.up, np.array([math.radians(s.placement_deg or 0.0)]))
        tilt = s.g * (plate.vector[0] * east[0] + plate.vector[1] * north[0])
        ys.append(s.accel.mean(axis=0) - tilt)
    coef, *_ = np.linalg.lstsq(a, np.array(ys), rcond=None)
    c = np.asarray(coef[:3].T)
    return [replace(s, tilt_matrix=c) if s.kind in ("static", "turn") else s for s in signals]


def _matrix_from_centres(signals: Sequence[RecordSignals], plate: PlateTilt) -> np.ndarray | None:
    """The accelerometer's matrix (3, 3) free of the tilt without the statics' headings: the
    diagonal and the biases from each axis's pair of static faces (gravity along the axis: the
    tilt enters as its square), the column of a turn's axis k from its circle's centre (the
    horizontal channels less their biases, over ±g: the tilt draws the circle about it; the
    mean of the turns about k). None unless both faces of every axis and a turn about every
    axis are there."""
    c = np.eye(3)
    bias = np.zeros(3)
    for k in range(3):
        pair = [s for s in signals if s.kind == "static" and abs(abs(float(s.up[k])) - 1) < 1e-6]
        plus = [float(s.accel[:, k].mean()) for s in pair if s.up[k] > 0]
        minus = [float(s.accel[:, k].mean()) for s in pair if s.up[k] < 0]
        if not plus or not minus:
            return None
        bias[k] = 0.5 * (float(np.mean(plus)) + float(np.mean(minus)))
        c[k, k] = 0.5 * (float(np.mean(plus)) - float(np.mean(minus))) / pair[0].g
    cols: dict[int, list[np.ndarray]] = {0: [], 1: [], 2: []}
    for circle in plate.circles:
        turn = next(s for s in signals if s.name == circle.record)
        k = int(np.argmax(np.abs(turn.up)))
        hor = [i for i in range(3) if i != k]
        col = np.zeros(3)
        col[hor] = (circle.centre - bias[hor]) / (turn.g * float(turn.up[k]))
        cols[k].append(col)
    if not all(cols.values()):
        return None
    for k, v in cols.items():
        m = np.mean(v, axis=0)
        c[[i for i in range(3) if i != k], k] = m[[i for i in range(3) if i != k]]
    return c


# ---- the turn axis: where gravity sits in the body while the cube turns ---------------------
#: a turn whose axis sits further than this from the static seat on the same face is named
#: tilted (and beyond what the plate's tilt and the noise allow), rad: 5 mrad (0.3°), above a
#: hand re-seating a cube on a clean plate
SEAT_TOL_RAD = 0.005


@dataclass(frozen=True)
class TurnAxis:
    """Where one turn record's axis sits in the body against the static record(s) of the same
    face: ``lean`` (3,) rad, the axis's unit vector minus the nominal up (zero along up);
    ``sd`` rad its noise σ per component; ``bound`` rad how far the plate's tilt at the
    statics' unknown heading can move it (0 when their heading is recorded)."""

    record: str
    up: np.ndarray
    statics: tuple[str, ...]
    lean: np.ndarray
    sd: float
    bound: float

    @property
    def size(self) -> float:
        """|lean|, rad."""
        return float(np.linalg.norm(self.lean))

    @property
    def tilted(self) -> bool:
        """The turn was made about an axis off the static seat beyond what the plate allows
        (:attr:`bound`) plus a re-seating (:data:`SEAT_TOL_RAD`) or the noise (3σ), whichever
        is larger."""
        return self.size > self.bound + max(SEAT_TOL_RAD, 3.0 * self.sd)

    @property
    def axis(self) -> np.ndarray:
        """(3,) the turn axis in the body, a unit vector (the nominal up leaned): the lean is
        what the horizontal accelerometers read of g, so its components are the unit axis's own
        (sines), and along up it keeps √(1 − |lean|²). Normalising up + lean instead takes them
        for tangents: the axis falls short across by |lean|²/2 of itself (0.15 mrad at 5°,
        the gyro cross-axis pulls' sd 1.7 there) and long along up by |lean|⁴/2 (its scale)."""
        along = math.sqrt(max(1.0 - float(self.lean @ self.lean), 0.0))
        return np.asarray(self.lean + along * self.up)

    def line(self) -> str:
        """The reader's sentence: the tilt, the gyro cross-axis it would fake, the correction."""
        k = int(np.argmax(np.abs(self.up)))
        up = ("+" if self.up[k] > 0 else "-") + "xyz"[k]
        fake = ", ".join(
            f"gyro {'xyz'[i]} {self.lean[i] * 360.0:+.2f}°/turn ({self.lean[i]:+.4f} of the rate)"
            for i in range(3) if i != k
        )  # fmt: skip
        out = (
            f"{self.record}: turned about an axis {1e3 * self.size:.1f} mrad "
            f"({math.degrees(self.size):.2f}°) off {up} — the accelerometer during the turn puts "
            f"gravity that far from where {' and '.join(self.statics)} has it (the cube was not "
            f"seated flat while it turned). A tilted turn puts part of its rate on the other "
            f"gyros ({fake}), which a fit would take for cross-axis sensitivity: the turn's "
            "reference rate is taken along the measured axis instead, and the turn's "
            f"cross-axis integrals carry that measurement's σ (± {1e3 * self.sd:.2f} mrad of "
            "the rate), so the fitted cross-axis values' σ include the geometry"
        )
        if self.bound > 0:
            out += (
                f"; the axis is uncertain by up to {1e3 * self.bound:.1f} mrad (the plate's "
                "tilt at the statics' unknown heading), and so are the gyro cross-axis values "
                "of this axis — record placement_heading_deg or level the plate"
            )
        return out


def turn_axes(signals: Sequence[RecordSignals], plate: PlateTilt | None) -> list[TurnAxis]:
    """Each turn record's axis against the static records of the same face (the circle's
    centre of :func:`turn_circle` against their mean horizontal readings: a bias, a
    misalignment and a face error are the same in both and cancel; the plate's tilt at the
    statics' heading is removed when it is recorded in the plate's frame, else bounds the
    result)."""
    if plate is None:
        return []
    cal = _accel_calibration(signals)
    out = []
    for c in plate.circles:
        sig = next(s for s in signals if s.name == c.record)
        same = [s for s in signals if s.kind == "static" and _close(s.up, sig.up)]
        if not same:
            continue
        k = int(np.argmax(np.abs(sig.up)))
        hor = [i for i in range(3) if i != k]
        reads, var = [], []
        known = plate.frame == "the fence" and all(s.placement_deg is not None for s in same)
        for st in same:
            m = st.accel[:, hor].mean(axis=0)
            if known:
                east, north = plate_axes(st.up, np.array([math.radians(st.placement_deg or 0.0)]))
                m = m - st.g * (plate.vector[0] * east[0, hor] + plate.vector[1] * north[0, hor])
            reads.append(m)
            var.append(st.accel[:, hor].var(axis=0) / len(st.t_s))
        static = np.zeros(3)
        static[hor] = np.mean(reads, axis=0)
        static[k] = float(np.mean([st.accel[:, k].mean() for st in same]))
        turn = static.copy()
        turn[hor] = c.centre
        sd = math.sqrt(float(np.max(c.centre_var + np.mean(var, axis=0) / len(same)))) / sig.g
        lean = np.zeros(3)
        lean[hor] = (cal(turn) - cal(static))[hor] / sig.g
        bound = 0.0 if known else plate.size + 2.0 * plate.size_sd
        out.append(TurnAxis(c.record, np.asarray(sig.up, dtype=float),
                            tuple(s.name for s in same), lean, sd, bound))  # fmt: skip
    return out


def _close(a: np.ndarray, b: np.ndarray) -> bool:
    """``np.allclose(a, b)`` of two finite up vectors (3,), in plain arithmetic: it is asked
    for every static record against every turn."""
    return all(
        abs(x - y) <= 1e-8 + 1e-5 * abs(y) for x, y in zip(a.tolist(), b.tolist(), strict=True)
    )


def _accel_calibration(
    signals: Sequence[RecordSignals],
) -> Callable[[np.ndarray], np.ndarray]:
    """The accelerometer's bias and scale-and-misalignment matrix from the static records'
    means (f = b + C·g·up, least squares), as the map from a reading (3,) m/s² to the specific
    force; the identity when the statics do not determine them. A lean read through it is
    free of the scale factors and cross-axis terms (a few % of it otherwise)."""
    st = [s for s in signals if s.kind == "static"]
    a = np.array([np.concatenate([s.g * s.up, [1.0]]) for s in st]) if st else np.zeros((0, 4))
    if len(st) < 4 or np.linalg.matrix_rank(a) < 4:
        return lambda f: np.asarray(f, dtype=float)
    y = np.array([s.accel.mean(axis=0) for s in st])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    c_inv, b = np.linalg.inv(coef[:3].T), coef[3]
    return lambda f: np.asarray(c_inv @ (np.asarray(f, dtype=float) - b))


def resolve_turn_axes(
    signals: Sequence[RecordSignals], axes: Sequence[TurnAxis]
) -> tuple[list[RecordSignals], list[TurnAxis]]:
    """The records with each tilted turn's reference rate and specific force along its
    measured axis (``axes``: :func:`turn_axes`, :attr:`TurnAxis.tilted`): the gyro cross-axis
    values such a turn would fake are corrected by the tilt the accelerometer shows. Returns
    the records and the tilted turns (their :meth:`TurnAxis.line` tells the reader)."""
    out = list(signals)
    tilted = [a for a in axes if a.tilted]
    for a in tilted:
        i = next(j for j, s in enumerate(out) if s.name == a.record)
        s = out[i]
        w = s.rate @ s.up
        out[i] = replace(s, rate=w[:, None] * a.axis[None, :],
                         force=np.tile(s.g * a.axis, (len(s.t_s), 1)))  # fmt: skip
    return out, tilted


# ---- what the tilt did to the accelerometer's bias estimates (the report's lines) ------------
def bias_note(
    signals: Sequence[RecordSignals], stderr: Mapping[str, float], g: float
) -> str | None:
    """The plate's tilt in mrad and degrees and its share of each §3 accelerometer bias
    estimate (a face pair's mean, where the channel lies horizontal): exact where the statics'
    headings are recorded in the plate's frame, else the bound g·tilt; and, when that share
    exceeds 3σ of the fitted bias (``stderr``: A0x … by name), the advice to level the plate
    or record the headings. None on a plate the rests do not show tilted."""
    plate = session_plate(signals)
    if plate is None or plate.p_level >= LEVEL_P:
        return None
    parts, limits = [], []
    for i in range(3):
        shares = []
        for j in (k for k in range(3) if k != i):
            faces = [s for s in signals if s.kind == "static" and abs(abs(s.up[j]) - 1.0) < 1e-6]
            if not faces:
                continue
            if plate.frame == "the fence" and all(s.placement_deg is not None for s in faces):
                v = []
                for s in faces:
                    e, n = plate_axes(s.up, np.array([math.radians(s.placement_deg or 0.0)]))
                    v.append(g * (plate.vector[0] * e[0, i] + plate.vector[1] * n[0, i]))
                shares.append((f"{'xyz'[j]} pair {float(np.mean(v)):+.4f}", abs(np.mean(v))))
            else:
                shares.append((f"{'xyz'[j]} pair up to ±{g * plate.size:.4f}", g * plate.size))
        if not shares:
            continue
        name = f"A0{'xyz'[i]}"
        parts.append(f"{name} from the " + ", ".join(t for t, _ in shares))
        worst = max(x for _, x in shares)
        sd = stderr.get(name, math.nan)
        if math.isfinite(sd) and worst > 3.0 * sd:
            limits.append(f"{name} (±{worst:.4f} against its σ {sd:.4f})")
    if not parts:
        return None
    out = (
        f"plate tilt {1e3 * plate.size:.2f} ± {1e3 * plate.size_sd:.2f} mrad "
        f"({math.degrees(plate.size):.3f}°); its share of the accelerometer bias estimates "
        "(method.md §3, a face pair's mean, m/s²): " + "; ".join(parts)
    )
    if limits:
        out += (
            f" — the tilt limits {', '.join(limits)}: level the plate (below 1 mrad) or record "
            "placement_heading_deg in every record"
        )
    return out
