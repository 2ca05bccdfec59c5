"""Poses without a cube: the multi-position method (Tedaldi, Pretto, Menegatti, ICRA 2014).

A pose is a rest at an attitude nobody set (:mod:`host.session.records`): the calibrated
specific force there has the magnitude of local gravity and its direction, the pose's attitude,
is an unknown of the record. The fit is the engine's one linear least squares
(:mod:`host.model.fit`): each pose's rows are block means as a static face's, read against
gravity along a first estimate of its attitude (:func:`preliminary_accel`, :func:`attitudes`),
and the attitude's correction is two small angles of the record (:func:`attitude_basis`; the
term's columns restricted to that record, :data:`host.model.catalogue.misalignment`), so the
linearisation error is the square of the first estimate's error (1e-4 rad: 1e-7 g).

Without any record of a set attitude (a face, a turn) the frame's three rotation angles are not
determined: a rotation of every pose together with the accelerometer's axes changes no reading.
:data:`FRAME_FIXED` names the three misalignments the convention of imu_tk fixes at zero and
:func:`frame_note` the combinations the records determine whatever the frame.

A move between two poses reads the gyro: the calibrated rate, integrated from one rest to the
next with the attitude kinematics exact (:func:`rotation_steps`, :func:`propagate`), turns the
gravity seen at the first rest into the gravity seen at the next (:func:`move_geometry`); its
two rows (:func:`move_rows`) are linearised about the gyro's first estimate from the moves
alone (:func:`preliminary_gyro`). Pure functions over numpy arrays; the rows join a dataset in
:mod:`host.model.moves`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from host.session.observations import Observation
from host.session.records import Record

#: imu_tk's "body" frame (its CalibratedTriad, Tedaldi et al. §III): the accelerometer's axes as
#: a skew basis T (a calibrated reading is T·K·(raw − b), T upper triangular): its x axis is the
#: frame's x, its y axis lies in the frame's xy plane. In this model's terms (a channel reads
#: the projection on its sensing direction, (I + Ma) upper triangular) that fixes these three
#: accelerometer misalignments at zero
FRAME_FIXED = ("Ayz", "Azy", "Azx")
#: what the records determine of the accelerometer's misalignments whatever the frame: each
#: pair moves together under a rotation of the frame (its non-orthogonality)
FRAME_FREE_PAIRS = (("Axz", "Ayz"), ("Axy", "Azy"), ("Ayx", "Azx"))
#: the gyro's misalignments are determined against the accelerometer's: G·· − A··
GYRO_MISALIGNMENTS = ("Gxz", "Gxy", "Gyz", "Gyx", "Gzy", "Gzx")

#: Gauss-Newton of the preliminary fit: at most this many steps, until a step moves < this
_MAX_STEPS = 50
_STEP_TOL = 1e-12


def _upper(p: np.ndarray) -> np.ndarray:
    """(3, 3) I + Ma from the six numbers (the three scales, Ma01, Ma02, Ma12)."""
    m = np.diag(1.0 + p[:3])
    m[0, 1], m[0, 2], m[1, 2] = p[3], p[4], p[5]
    return m


def _magnitude_residuals(p: np.ndarray, means: np.ndarray, g: float) -> np.ndarray:
    """(P,) |(I + Ma)⁻¹·(mean − b)| − g of every rest, m/s² (``p``: 6 of :func:`_upper`, b)."""
    force = np.linalg.solve(_upper(p[:6]), (means - p[6:9]).T).T
    return np.asarray(np.linalg.norm(force, axis=1) - g)


def preliminary_accel(means: np.ndarray, g: float) -> tuple[np.ndarray, np.ndarray]:
    """How the accelerometer reads a specific force, from the rests alone, in imu_tk's frame
    (:data:`FRAME_FIXED`): (I + Ma) (3, 3) upper triangular and the bias b (3,) m/s² that make
    every rest's specific force |(I + Ma)⁻¹·(mean − b)| closest to ``g`` m/s² (Gauss-Newton
    on ``means`` (P, 3) m/s², P ≥ 9 rests in many attitudes). ValueError when the rests do not
    determine the nine numbers (too few, or their attitudes too alike)."""
    means = np.asarray(means, dtype=np.float64)
    if means.shape[0] < 9:
        raise ValueError(f"{means.shape[0]} rests: the accelerometer needs at least 9 poses")
    p = np.zeros(9)
    for _ in range(_MAX_STEPS):
        r = _magnitude_residuals(p, means, g)
        jac = np.empty((len(r), 9))
        for q in range(9):
            dp = np.zeros(9)
            dp[q] = 1e-7
            jac[:, q] = (_magnitude_residuals(p + dp, means, g) - r) / 1e-7
        sv = np.linalg.svd(jac, compute_uv=False)
        if sv[-1] < 1e-6 * sv[0]:
            raise ValueError("the poses' attitudes are too alike to determine the accelerometer")
        step, *_ = np.linalg.lstsq(jac, -r, rcond=None)
        p = p + step
        if float(np.max(np.abs(step))) < _STEP_TOL * max(1.0, g):
            break
    return _upper(p[:6]), p[6:9].copy()


def attitudes(means: np.ndarray, matrix: np.ndarray, bias: np.ndarray) -> np.ndarray:
    """(P, 3) unit vectors: each rest's up direction in the frame of ``matrix`` (I + Ma) and
    ``bias`` (m/s²), from its accelerometer ``means`` (P, 3) m/s²."""
    force = np.linalg.solve(np.asarray(matrix), (np.asarray(means) - np.asarray(bias)).T).T
    return np.asarray(force / np.linalg.norm(force, axis=1, keepdims=True))


def attitude_basis(up: np.ndarray) -> np.ndarray:
    """(2, 3) two orthonormal directions across the unit vector ``up``: a pose's attitude
    correction is up + a·e₁ + b·e₂ (rad; rotation about up moves no gravity). e₁ lies in the
    plane of up and the chip axis least along it, e₂ = up × e₁."""
    u = np.asarray(up, dtype=np.float64)
    u = u / np.linalg.norm(u)
    k = int(np.argmin(np.abs(u)))
    axis = np.zeros(3)
    axis[k] = 1.0
    e1 = axis - (axis @ u) * u
    e1 /= np.linalg.norm(e1)
    return np.array([e1, np.cross(u, e1)])


@dataclass(frozen=True, eq=False)
class FirstEstimates:
    """What a session's poses and moves are read against before the fit: the pose observations
    with their attitude's first estimate (``observations``), the accelerometer's first
    estimate (I + Ma, b m/s²; None without enough rests) and the gyro's (I + Mg; identity
    until :meth:`with_moves`)."""

    observations: dict[str, Observation]
    accel_matrix: np.ndarray | None = None
    accel_bias: np.ndarray | None = None
    gyro_matrix: np.ndarray = field(default_factory=lambda: np.eye(3))

    def with_moves(
        self, records: Mapping[str, Record], obs: Mapping[str, Observation], rest_fit: np.ndarray
    ) -> FirstEstimates:
        """The gyro's first estimate from the session's moves (:func:`preliminary_gyro`), the
        rests' gyro bias and g-sensitivity ``rest_fit`` (4, 3) (rows: g-sensitivity per g of
        force x, y, z, then the bias, °/s) taken out; as it is without 5 moves or when they do
        not determine it."""
        inputs = []
        for name, o in obs.items():
            if o.kind == "move":
                rec = records[name]
                start, end = obs[rec.move_from].up, obs[rec.move_to].up
                gyro = self.gyro_less_rest(rec, rest_fit)
                inputs.append(MoveInput(rec.t_ms / 1000.0, gyro, start, attitude_basis(end)))
        try:
            return replace(self, gyro_matrix=preliminary_gyro(inputs))
        except ValueError:
            return self

    def force(self, record: Record) -> np.ndarray:
        """(N, 3) the specific force of ``record``'s samples through the accelerometer's first
        estimate, m/s² (as measured without one)."""
        if self.accel_matrix is None or self.accel_bias is None:
            return record.accel.copy()
        return np.linalg.solve(self.accel_matrix, (record.accel - self.accel_bias).T).T

    def gyro_less_rest(self, record: Record, rest_fit: np.ndarray) -> np.ndarray:
        """(N, 3) ``record``'s gyro less the rests' bias and g-sensitivity (``rest_fit``)."""
        force = self.force(record)
        g = float(np.median(np.linalg.norm(force, axis=1))) or 1.0
        return np.asarray(record.gyro - (force / g) @ rest_fit[:3] - rest_fit[3])

    def reference_rate(self, record: Record, rest_fit: np.ndarray) -> np.ndarray:
        """(N, 3) a move's body rate as the first estimates read it, °/s: the reference its
        rows are linearised about (:func:`move_geometry`)."""
        gyro = self.gyro_less_rest(record, rest_fit)
        return np.asarray(np.linalg.solve(self.gyro_matrix, gyro.T).T)


def first_estimates(obs: Mapping[str, Observation], g: float) -> FirstEstimates:
    """The pose observations of ``obs`` (record name -> observation) with their attitude's first
    estimate from every rest's accelerometer mean (:func:`preliminary_accel`,
    :func:`attitudes`; ``g`` m/s²); as they are when the rests do not determine the
    accelerometer (then the first estimate stays the normalised mean)."""
    poses = [n for n, o in obs.items() if o.kind == "pose"]
    rests = [n for n, o in obs.items() if o.accel is not None]
    if not poses:
        return FirstEstimates({})
    try:
        matrix, bias = preliminary_accel(np.array([obs[n].accel for n in rests]), g)
    except ValueError:
        return FirstEstimates({n: obs[n] for n in poses})
    ups = attitudes(np.array([obs[n].accel for n in poses]), matrix, bias)
    return FirstEstimates(
        {
            n: replace(obs[n], up=u, force=u.copy(), rate=obs[n].rate @ obs[n].up * u)
            for n, u in zip(poses, ups, strict=True)
        },
        matrix,
        bias,
    )


def frame_note() -> str:
    """The result's line saying which convention fixes the frame and what is determined."""
    pairs = ", ".join(f"{a} − {b}" for a, b in FRAME_FREE_PAIRS)
    return (
        "frame: no record has a set attitude (poses only), so the frame's three rotation "
        "angles are fixed by imu_tk's convention (Tedaldi, Pretto, Menegatti, ICRA 2014): the "
        "accelerometer's x axis is x and its y axis lies in the xy plane (as a skew basis), "
        f"i.e. {', '.join(FRAME_FIXED)} = 0. Determined whatever the frame: every scale, bias "
        f"and g-sensitivity, the accelerometer's non-orthogonality {pairs} (here the first of "
        "each pair), and each gyro misalignment less the accelerometer's of the same name "
        "(G·· − A··)"
    )


# ---- moves: the gyro between two rests --------------------------------------------------------
def _skew(v: np.ndarray) -> np.ndarray:
    """(..., 3, 3) the cross-product matrices of vectors ``v`` (..., 3)."""
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return out


def rotation_steps(t_s: np.ndarray, rate_dps: np.ndarray) -> np.ndarray:
    """(N − 1, 3, 3) how a room-fixed vector seen in the body turns over each sample interval:
    exp(−[ω̄·Δt]×) (Rodrigues, exact for a constant rate), ω̄ the mean of the interval's two
    body rates ``rate_dps`` (N, 3) °/s at times ``t_s`` (N,) s."""
    phi = np.radians(0.5 * (rate_dps[1:] + rate_dps[:-1])) * np.diff(t_s)[:, None]
    angle = np.linalg.norm(phi, axis=1)
    k = _skew(-phi)
    small = angle < 1e-8
    safe = np.where(small, 1.0, angle)
    a = np.where(small, 1.0, np.sin(safe) / safe)
    b = np.where(small, 0.5, (1.0 - np.cos(safe)) / safe**2)
    return np.eye(3) + a[:, None, None] * k + b[:, None, None] * (k @ k)


def propagate(steps: np.ndarray) -> np.ndarray:
    """(N, 3, 3) R_n = A_{n−1}·…·A_0 (R_0 = I): what a room-fixed vector seen in the body at
    the first sample is at sample n, from :func:`rotation_steps` ``steps`` (N − 1, 3, 3)."""
    out = np.empty((len(steps) + 1, 3, 3))
    out[0] = np.eye(3)
    for n, a in enumerate(steps):
        out[n + 1] = a @ out[n]
    return out


def move_geometry(
    t_s: np.ndarray, rate_dps: np.ndarray, up_from: np.ndarray, across_to: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A move read against gravity: the body rate ``rate_dps`` (N, 3) °/s at ``t_s`` (N,) s,
    integrated exactly (:func:`rotation_steps`), turns gravity's direction ``up_from`` (3,) at
    the first sample into R·up_from at the last. Returns (the miss along the two directions
    ``across_to`` (2, 3) (across the next rest's attitude), rad (2,); the weights (2, N, 3), s,
    that turn a change of the rate δω(t) (°/s) into the change of that miss, in °:
    Σₜ w·δω; the whole turn R (3, 3)). A change δω at time t moves the end by
    R_T·R_tᵀ·(u(t) × δω) (the linearised kinematics), so w_k(t) = (R_t·R_Tᵀ·e_k) × u(t) times
    the trapezoid weight of sample t."""
    rot = propagate(rotation_steps(t_s, rate_dps))
    ups = rot @ up_from
    miss = across_to @ ups[-1]  # the next rest's attitude is across both directions
    lever = np.einsum("nij,kj->nki", rot, across_to @ rot[-1])  # R_t·R_Tᵀ·e_k, (N, 2, 3)
    w = np.zeros(len(t_s))
    dt = np.diff(t_s)
    w[1:] += dt / 2
    w[:-1] += dt / 2
    weights = np.cross(lever, ups[:, None, :]) * w[:, None, None]
    return miss, np.transpose(weights, (1, 0, 2)), rot[-1]


@dataclass(frozen=True, eq=False)
class MoveInput:
    """One move for :func:`preliminary_gyro`: sample times ``t_s`` (N,) s, the gyro less its
    bias and g-sensitivity ``gyro_dps`` (N, 3) °/s, gravity's direction at the rest before
    ``up_from`` (3,) and two directions across it at the rest after ``across_to`` (2, 3)."""

    t_s: np.ndarray
    gyro_dps: np.ndarray
    up_from: np.ndarray
    across_to: np.ndarray


def preliminary_gyro(moves: Sequence[MoveInput], steps: int = 20) -> np.ndarray:
    """(3, 3) I + Mg, how the gyro reads a rate, from the moves alone: the calibrated rate
    (I + Mg)⁻¹·gyro, integrated exactly over each move (:func:`move_geometry`), brings gravity
    from the rest before to the rest after (Gauss-Newton on both directions across it, every
    move alike; at least 5 moves about different axes). ValueError when they do not determine
    the nine numbers."""
    if len(moves) < 5:
        raise ValueError(f"{len(moves)} moves: the gyro needs at least 5")
    m = np.eye(3)
    for _ in range(steps):
        misses, jac = [], []
        for mv in moves:
            rate = np.linalg.solve(m, mv.gyro_dps.T).T
            miss, w, _ = move_geometry(mv.t_s, rate, mv.up_from, mv.across_to)
            misses.append(np.degrees(miss))
            jac.append(-np.einsum("kna,nb->kab", w, rate).reshape(2, 9))
        j, r = np.vstack(jac), np.concatenate(misses)
        sv = np.linalg.svd(j, compute_uv=False)
        if sv[-1] < 1e-6 * sv[0]:
            raise ValueError("the moves' axes are too alike to determine the gyro")
        step, *_ = np.linalg.lstsq(j, -r, rcond=None)
        m = m + step.reshape(3, 3)
        if float(np.max(np.abs(step))) < 1e-10:
            break
    return m


#: (term name, pose record) -> the rows of other records that read that pose's own unknowns,
#: each (row index, its coefficient per unknown): a move's rows read both poses' attitudes
RecordLinks = dict[tuple[str, str], list[tuple[int, np.ndarray]]]


@dataclass(frozen=True, eq=False)
class MoveRows:
    """A move's two rows (:func:`move_rows`): per row the gyro's weights (3, N) s (one per
    channel: the row is Σ over the channels of weights·samples), the measured and the ideal
    sensor's value (°), its noise σ (°), and its coefficients on the attitude (a, b) of the
    pose before and of the pose after (° per rad)."""

    weights: np.ndarray  # (2, 3, N)
    y: np.ndarray  # (2,)
    nominal: np.ndarray  # (2,)
    sigma: np.ndarray  # (2,)
    from_coef: np.ndarray  # (2, 2)
    to_coef: np.ndarray  # (2, 2)


def move_rows(
    t_s: np.ndarray,
    gyro_dps: np.ndarray,
    rate_dps: np.ndarray,
    up_from: np.ndarray,
    up_to: np.ndarray,
    white: np.ndarray,
    floor: float = 0.0,
) -> MoveRows:
    """A move's rows, linearised about the reference rate ``rate_dps`` (N, 3) °/s (the first
    estimates' reading of the gyro ``gyro_dps``, :meth:`FirstEstimates.reference_rate`) and
    the poses' first attitudes ``up_from``, ``up_to``: the calibrated rate must carry gravity
    from the one to the other (:func:`move_geometry`), along two directions across ``up_to``,
    chosen so that the gyro's white noise (``white`` (3,) variance·τ of one sample per channel,
    (°/s)²) and its noise floor (``floor`` °/s: a bias of the record's own on each channel, as
    a turn integral carries it) leave the two rows uncorrelated. Row k: Σ_a w_ka·gyro_a +
    miss_k (°) against Σ_a w_ka·rate_a, so that the model's gyro terms (their columns
    w_ka·regressors) and the attitudes' corrections explain their difference."""
    across = attitude_basis(up_to)
    miss, w, rot = move_geometry(t_s, rate_dps, up_from, across)
    total = w.sum(axis=1)  # (2, 3): what a constant rate on each channel moves the miss by
    cov = np.einsum("kna,lna,a->kl", w, w, white) + floor**2 * (total @ total.T)
    lam, vec = np.linalg.eigh(cov)
    w2 = np.einsum("kl,kna->lan", vec, w)
    miss2 = vec.T @ np.degrees(miss)
    e2 = vec.T @ across
    return MoveRows(
        weights=w2,
        y=np.einsum("lan,na->l", w2, gyro_dps) + miss2,
        nominal=np.einsum("lan,na->l", w2, rate_dps),
        sigma=np.sqrt(np.maximum(lam, 1e-30)),
        from_coef=-np.degrees(e2 @ rot @ attitude_basis(up_from).T),
        to_coef=np.degrees(e2 @ across.T),
    )
