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

Where the rests draw no circle (a turn made in one motion, resting only at its ends), the
tilt as each turn sees it is read from its motion instead (:func:`motion_circles`,
:mod:`host.model.turn_motion`), and where they do, the motion's reading is printed beside the
rests' (they should agree). The axis each turn was made about, from its circle's centre, is
:mod:`host.model.turn_axis`'s.

Units: rad for tilts, m/s² for specific force, degrees for headings (counter-clockwise seen
from above, from the fence to the reference axis).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from host.model.geometry import plate_axes
from host.model.noise import still_runs
from host.model.signals import RecordSignals
from host.model.stats import chi2_sf
from host.model.turn_motion import motion_tilts

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
    #: what it was read from: "rests" (the still moments inside the turn) or "motion"
    #: (every sample: :func:`host.model.turn_motion.motion_tilts`, ``n_blocks`` moving blocks
    #: beside the ``n_rests`` rests)
    source: str = "rests"
    n_blocks: int = 0
    #: the same record's tilt read from its motion, beside one read from its rests (None)
    motion: TurnCircle | None = None
    #: read from the motion: the named variance components fitted with it, m/s² of a row
    #: beyond its white noise — the seating at the rests, the hand on the moving blocks
    scatter: tuple[float, float] = (0.0, 0.0)

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
            f"toward {self.azimuth_deg:.0f}° from {self.frame}, read from {self._source()}: "
            f"the horizontal accelerometers draw a circle of radius "
            f"g·tilt = {g * self.size:.4f} m/s² about the turn axis"
        ]
        for c in self.circles:
            read = (
                f"from {c.n_rests} rests"
                if c.source == "rests"
                else f"from its motion ({c.n_blocks} moving blocks, {c.n_rests} rests)"
            )
            out.append(
                f"  {c.record}: circle radius {g * c.size:.4f} ± {g * c.size_sd:.4f} m/s² "
                f"({1e3 * c.size:.2f} mrad) {read}, residual rms {c.rms:.4f} m/s²"
            )
        out.extend(self._motion_lines())
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

    def _source(self) -> str:
        """What the tilt was read from, in words."""
        rests = sum(c.source == "rests" for c in self.circles)
        moved = len(self.circles) - rests
        if not moved:
            return f"the rests of {rests} turns"
        seat, hand = next(c.scatter for c in self.circles if c.source == "motion")
        scatter = _scatter(seat, hand)
        what = f"the motion of {moved} turns (every sample, with the lever arm — {scatter})"
        return what if not rests else f"the rests of {rests} turns and {what}"

    def _motion_lines(self) -> list[str]:
        """The tilt read again from the motion of the turns whose rests gave it (every sample,
        with the lever arm and the hand), and whether the two agree."""
        moved = [c.motion for c in self.circles if c.motion is not None]
        if not moved or any(c.source != "rests" for c in self.circles):
            return []
        other = plate_from_rests(moved)
        if other is None:
            return []
        diff = other.size - self.size
        z = diff / math.hypot(other.size_sd, self.size_sd)
        word = "agree" if abs(z) < 3.0 else "DISAGREE"
        return [
            f"  from the motion of the same {len(moved)} turns (every sample: the rests and "
            f"the moving blocks, jointly with the lever arm — {_scatter(*moved[0].scatter)}): "
            f"{1e3 * other.size:.2f} ± "
            f"{1e3 * other.size_sd:.2f} mrad; the rests and the motion {word} "
            f"({1e3 * diff:+.2f} mrad, {z:+.1f}σ)"
        ]


def _scatter(seat: float, hand: float) -> str:
    """The motion fit's variance components in words, m/s²."""
    return (
        f"beyond the white noise the seating {seat:.2g} m/s² at a rest, the hand {hand:.2g} "
        "on a moving block"
    )


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
    short pauses between quarter turns count), carrying the tilt its motion shows
    (:attr:`TurnCircle.motion`); where the rests draw none (a turn in one motion, resting only
    at its ends), the tilt from its motion alone (:func:`motion_circles`). None without
    static records."""
    statics = [s for s in signals if s.kind == "static"]
    if not statics:
        return []
    gyro_sd = np.median([s.gyro.std(axis=0) for s in statics], axis=0)
    motion = {c.record: c for c in motion_circles(signals, gyro_sd)}
    circles = []
    for s in signals:
        if s.kind != "turn":
            continue
        up_k = int(np.argmax(np.abs(s.up)))
        sd = max(float(gyro_sd[up_k]), REST_RATE_DPS / 4.0)
        runs = still_runs(s.rate @ s.up, s.t_s - s.t_s[0], sd, trim_s=REST_TRIM_S, min_s=0.1)
        c = turn_circle(s, runs)
        if c is not None:
            circles.append(replace(c, motion=motion.get(s.name)))
        elif s.name in motion:
            circles.append(motion[s.name])
    return circles


def motion_circles(signals: Sequence[RecordSignals], gyro_sd: np.ndarray) -> list[TurnCircle]:
    """Each turn record's tilt read from every sample of its motion, jointly with one lever
    arm and the hand's scatter (:func:`host.model.turn_motion.motion_tilts`), as the circle
    it draws in the turn's own angle; ``gyro_sd`` (3,) °/s the static records' gyro noise."""
    statics = [s for s in signals if s.kind == "static"]
    accel_var = np.median([s.accel.var(axis=0) for s in statics], axis=0)
    fit = motion_tilts(signals, gyro_sd, accel_var)
    if fit is None:
        return []
    placed = {s.name: s.placement_deg for s in signals}
    return [
        TurnCircle(
            m.record,
            m.tilt,
            m.cov,
            m.rms,
            m.n_rests,
            placed[m.record],
            m.centre,
            m.centre_var,
            "motion",
            m.n_blocks,
            scatter=(fit.seating, fit.hand),
        )
        for m in fit.tilts
        if np.all(np.isfinite(m.cov))
    ]


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
    seats = statics_against_turns(signals, plate)
    lines = [*plate.lines(g, unknown), *([seats] if seats else [])]
    return out, ["; ".join(line.strip() for line in lines)]


def statics_against_turns(signals: Sequence[RecordSignals], plate: PlateTilt) -> str | None:
    """One geometry for statics and turns: the tilt the turns show predicts each static
    record's lean. A static on a face a turn was made on, read against that turn's circle
    centre (the body-fixed part of the face: bias, misalignment and the face's lean cancel),
    sees the plate's tilt at its own heading, of the tilt's size whatever the heading; where
    its heading is not recorded the size alone is the prediction. -> the sentence saying
    whether they agree (χ² of the sizes against the tilt's, p ≥ :data:`LEVEL_P`) and, where
    not, that the fixture's seating is what is left; None without such a static."""
    seen = []
    for k in range(3):
        on = [c for c in plate.circles if _up_axis(signals, c.record) == k]
        if not on:
            continue
        hor = [i for i in range(3) if i != k]
        centre = np.mean([c.centre for c in on], axis=0)
        centre_var = np.mean([c.centre_var for c in on], axis=0) / len(on)
        turn = next(s for s in signals if s.name == on[0].record)
        for st in signals:
            if st.kind != "static" or float(st.up @ turn.up) < 1.0 - 1e-6:
                continue
            scale = 1.0 if st.accel_matrix is None else np.diag(st.accel_matrix)[hor]
            lean = (st.accel[:, hor].mean(axis=0) - centre) / (st.g * scale)
            var = (centre_var + st.accel[:, hor].var(axis=0) / len(st.t_s)) / (st.g * scale) ** 2
            size = float(np.hypot(*lean))
            u = lean / max(size, 1e-12)
            seen.append((st.name, size, math.sqrt(float(u @ (var * u)))))
    if not seen:
        return None
    z = [(size - plate.size) / math.hypot(sd, plate.size_sd) for _, size, sd in seen]
    chi2 = float(np.sum(np.square(z)))
    p = chi2_sf(chi2, float(len(z)))
    sizes = ", ".join(f"{n} {1e3 * v:.2f} ± {1e3 * sd:.2f}" for n, v, sd in seen)
    head = (
        f"one geometry: the statics on the faces turned on, read against their turn's circle "
        f"centre, lean {sizes} mrad where the turns' tilt predicts {1e3 * plate.size:.2f} ± "
        f"{1e3 * plate.size_sd:.2f} at any heading: they "
    )
    if p >= LEVEL_P:
        return head + f"agree (χ² = {chi2:.1f} on {len(z)}, p = {p:.2g})"
    worst = max(abs(v - plate.size) for _, v, _ in seen)
    return head + (
        f"do not (χ² = {chi2:.1f} on {len(z)}, p = {p:.2g}): the statics were not seated as "
        f"the cube sat while it turned — what is left is the fixture's seating (a re-seating "
        f"or a face's lean of up to {1e3 * worst:.1f} mrad), which these records cannot tell "
        "apart"
    )


def seen_tilts_line(names: Sequence[str], values: Sequence[float], cov: np.ndarray) -> str | None:
    """After a fit with ``plate_tilt``: each static record's own view of the tilt (its
    ``seen_ref``/``seen_side``, where its heading is not recorded) against the session's tilt
    (``plate_tilt.east``/``.north``): one geometry predicts the same size on every record.
    ``names``, ``values`` and ``cov`` the fit's parameters and their covariance (a size's σ
    is along its direction: the two angles are correlated where the headings are unknown).
    -> the sentence (None without both)."""
    at = {n: i for i, n in enumerate(names)}

    def size_of(a: str, b: str) -> tuple[float, float]:
        i = [at[a], at[b]]
        v = np.asarray(values)[i]
        size = float(np.hypot(*v))
        u = v / max(size, 1e-12)
        return size, math.sqrt(max(float(u @ np.asarray(cov)[np.ix_(i, i)] @ u), 0.0))

    if "plate_tilt.east" not in at or "plate_tilt.north" not in at:
        return None
    size, size_sd = size_of("plate_tilt.east", "plate_tilt.north")
    seen = [
        (n.split(".")[1], *size_of(n, n.replace(".seen_ref", ".seen_side")))
        for n in sorted(at)
        if n.startswith("plate_tilt.") and n.endswith(".seen_ref")
    ]
    if not seen:
        return None
    z = [(v - size) / math.hypot(sd, size_sd) for _, v, sd in seen]
    chi2 = float(np.sum(np.square(z)))
    p = chi2_sf(chi2, float(len(z)))
    word = "agree" if p >= LEVEL_P else "do NOT agree: what is left is the fixture's seating"
    lo, hi = min(v for _, v, _ in seen), max(v for _, v, _ in seen)
    return (
        f"one geometry: the {len(seen)} statics' own views of the tilt are {1e3 * lo:.2f}–"
        f"{1e3 * hi:.2f} mrad in size against the session's {1e3 * size:.2f} ± "
        f"{1e3 * size_sd:.2f} mrad; they {word} (χ² = {chi2:.1f} on {len(z)}, p = {p:.2g})"
    )


def _up_axis(signals: Sequence[RecordSignals], record: str) -> int:
    """The body axis record ``record`` rests on (the largest component of its up)."""
    s = next(x for x in signals if x.name == record)
    return int(np.argmax(np.abs(s.up)))


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
