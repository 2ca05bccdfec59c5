"""Physics of the simulated bench: attitude of the cube, hand turns, gravity, Earth rate, room.

Frames and conventions (used by :mod:`host.bench.sim` and the ``sim://`` board):

- **World** frame: x east, y north, z up (ENU). Gravity is ``-g`` along z, so a resting
  accelerometer measures the specific force ``+g`` along the world up direction.
- **Body** frame: the nominal sensitive axes X, Y, Z engraved on the cube (= chip axes).
- An attitude is the rotation matrix ``R`` (3, 3) with ``v_world = R @ v_body``; arrays of
  attitudes are (N, 3, 3).
- Angular rates are body-frame rates. "ccw" is a positive rotation about the up axis seen from
  above (method.md §4), i.e. a positive rate on the body axis that points up.

Everything here is a pure function of numpy arrays (no random draws except in the ``random``
constructors, which take a ``numpy.random.Generator``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from host.model.geometry import pose_from_up

#: Earth's sidereal rotation rate, °/s (15.041 °/h)
EARTH_RATE_DPS = 360.0 / 86164.0905
_AXES = "xyz"


# --------------------------------------------------------------------------- rotations
def rot_axis(axis: int, angle_rad: np.ndarray | float) -> np.ndarray:
    """Rotation matrices about world/body axis ``axis`` (0, 1, 2) by ``angle_rad``.

    Returns (N, 3, 3) for an array of N angles, (3, 3) for a scalar.
    """
    a = np.asarray(angle_rad, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    out = np.zeros(a.shape + (3, 3))
    i, j = (axis + 1) % 3, (axis + 2) % 3
    out[..., axis, axis] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., i, j] = -s
    out[..., j, i] = s
    return out


def rot_vector(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """Rotation matrix (3, 3) about the unit vector ``axis`` by ``angle_rad`` (Rodrigues)."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    kx = skew(k)
    return np.eye(3) + math.sin(angle_rad) * kx + (1.0 - math.cos(angle_rad)) * (kx @ kx)


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix of a 3-vector: ``skew(a) @ b == cross(a, b)``."""
    x, y, z = np.asarray(v, dtype=np.float64)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def vee(m: np.ndarray) -> np.ndarray:
    """Inverse of :func:`skew` over the last two axes: (..., 3, 3) -> (..., 3)."""
    return 0.5 * np.stack(
        [m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]],
        axis=-1,
    )


def up_vector(name: str) -> np.ndarray:
    """Body up vector of a face name ``x_up`` ... ``z_dn`` (also accepts ``x_ccw`` -> +x)."""
    axis, _, side = name.partition("_")
    v = np.zeros(3)
    v[_AXES.index(axis)] = -1.0 if side == "dn" else 1.0
    return v


def pose(name: str) -> np.ndarray:
    """Attitude (3, 3) of a face name ``x_up`` ... ``z_dn`` on a level base."""
    return pose_from_up(up_vector(name))


# --------------------------------------------------------------------------- hand turns
def _bump_integral(t: np.ndarray, a: np.ndarray, length: np.ndarray) -> np.ndarray:
    """∫ sin²(π(s−a)/L) ds from a to t, clipped to the bump [a, a+L]; shapes broadcast."""
    u = np.clip(t - a, 0.0, length)
    return u / 2.0 - length / (4.0 * np.pi) * np.sin(2.0 * np.pi * u / length)


@dataclass(frozen=True)
class TurnProfile:
    """Rate about the up axis during a hand turn: a sum of overlapping sin² bumps.

    ``starts``/``lengths`` (s) of the bumps and their ``weights`` (°/s); the weights are scaled
    so the total angle is exactly ``angle_deg`` (signed; ±n·360 for n whole turns). The rate and
    its derivative are zero at both ends of ``[start, end]``, the rate never stays constant.
    """

    starts: tuple[float, ...]
    lengths: tuple[float, ...]
    weights: tuple[float, ...]

    @property
    def start(self) -> float:
        """Time the turn begins, s."""
        return min(self.starts)

    @property
    def end(self) -> float:
        """Time the turn ends, s."""
        return max(a + L for a, L in zip(self.starts, self.lengths, strict=True))

    @property
    def angle_deg(self) -> float:
        """Total angle, degrees."""
        return float(sum(w * L / 2.0 for w, L in zip(self.weights, self.lengths, strict=True)))

    def _arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return np.array(self.starts), np.array(self.lengths), np.array(self.weights)

    def angle(self, t: np.ndarray) -> np.ndarray:
        """Angle turned by time ``t`` (s), degrees."""
        a, L, w = self._arrays()
        t = np.asarray(t, dtype=np.float64)[..., None]
        return np.sum(w * _bump_integral(t, a, L), axis=-1)

    def rate(self, t: np.ndarray) -> np.ndarray:
        """Rate at time ``t`` (s), °/s."""
        a, L, w = self._arrays()
        t = np.asarray(t, dtype=np.float64)[..., None]
        inside = (t >= a) & (t <= a + L)
        return np.sum(np.where(inside, w * np.sin(np.pi * (t - a) / L) ** 2, 0.0), axis=-1)

    def peak_rate(self, n: int = 2000) -> float:
        """Largest |rate|, °/s (sampled finely)."""
        t = np.linspace(self.start, self.end, n)
        return float(np.max(np.abs(self.rate(t))))

    def scaled_in_time(self, factor: float) -> TurnProfile:
        """Same shape and angle, ``factor`` times longer (shorter if < 1), same start."""
        t0 = self.start
        return TurnProfile(
            starts=tuple(t0 + (a - t0) * factor for a in self.starts),
            lengths=tuple(L * factor for L in self.lengths),
            weights=tuple(w / factor for w in self.weights),
        )

    @staticmethod
    def random(
        rng: np.random.Generator,
        start_s: float,
        duration_s: float,
        angle_deg: float,
        max_peak_dps: float = 220.0,
    ) -> TurnProfile:
        """A hand-like profile over ``[start_s, start_s + duration_s]`` turning ``angle_deg``.

        Strokes of 1.0–2.2 s overlap; their strengths vary ±50 %. Redrawn until the peak rate
        is below ``max_peak_dps`` (falls back to equal strengths).
        """
        k = max(2, int(math.ceil((duration_s - 1.0) / 0.9)) + 1)
        for attempt in range(30):
            lengths = rng.uniform(1.0, 2.2, k) if attempt < 29 else np.full(k, 1.6)
            lengths = np.minimum(lengths, duration_s)
            frac = np.arange(k) / (k - 1)
            starts = start_s + frac * (duration_s - lengths)
            raw = rng.uniform(0.5, 1.5, k) if attempt < 29 else np.ones(k)
            raw = raw * angle_deg / float(np.sum(raw * lengths / 2.0))
            prof = TurnProfile(tuple(starts), tuple(lengths), tuple(raw))
            if prof.peak_rate() <= max_peak_dps:
                return prof
        return prof


@dataclass(frozen=True)
class Wobble:
    """Hand wobble about the world horizontal axes (east, north) during ``[start, end]``.

    Angle about each axis: ``amp · sin²(π(t−start)/D) · sin(2π f (t−start) + phase)``, zero
    (with zero rate) at both ends, so the net tilt after the turn is exactly zero.
    """

    start: float
    end: float
    amp_deg: tuple[float, float] = (0.0, 0.0)
    freq_hz: tuple[float, float] = (0.5, 0.7)
    phase: tuple[float, float] = (0.0, 0.0)

    def angles_and_rates(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 2) angles (rad) and (N, 2) rates (rad/s) about world east and north."""
        t = np.asarray(t, dtype=np.float64)[..., None]
        d = self.end - self.start
        u = np.clip(t - self.start, 0.0, d)
        inside = (t >= self.start) & (t <= self.end)
        amp = np.radians(np.array(self.amp_deg))
        f = np.array(self.freq_hz)
        ph = np.array(self.phase)
        env = np.sin(np.pi * u / d) ** 2
        denv = (np.pi / d) * np.sin(2.0 * np.pi * u / d)
        osc = np.sin(2.0 * np.pi * f * u + ph)
        dosc = 2.0 * np.pi * f * np.cos(2.0 * np.pi * f * u + ph)
        ang = amp * env * osc
        rate = np.where(inside, amp * (denv * osc + env * dosc), 0.0)
        return ang, rate

    @staticmethod
    def random(rng: np.random.Generator, start: float, end: float, amp_deg: float) -> Wobble:
        """Random wobble of amplitude up to ``amp_deg`` per axis."""
        return Wobble(
            start=start,
            end=end,
            amp_deg=(
                float(rng.uniform(0.3, 1.0) * amp_deg),
                float(rng.uniform(0.3, 1.0) * amp_deg),
            ),
            freq_hz=(float(rng.uniform(0.3, 1.2)), float(rng.uniform(0.3, 1.2))),
            phase=(float(rng.uniform(0, 2 * np.pi)), float(rng.uniform(0, 2 * np.pi))),
        )


# --------------------------------------------------------------------------- motions
@dataclass(frozen=True)
class Motion:
    """The cube resting in ``pose_body`` (3, 3) attitude; subclasses move it.

    ``kinematics(t)`` gives attitude (N, 3, 3) (body -> fixture frame, before the bench's
    heading and tilt) and body rate (N, 3) in rad/s.
    """

    attitude: tuple[tuple[float, ...], ...]

    @property
    def pose_matrix(self) -> np.ndarray:
        return np.array(self.attitude, dtype=np.float64)

    def kinematics(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=np.float64)
        r = np.broadcast_to(self.pose_matrix, t.shape + (3, 3)).copy()
        return r, np.zeros(t.shape + (3,))

    @property
    def moving(self) -> bool:
        return False


def _as_tuple(m: np.ndarray) -> tuple[tuple[float, ...], ...]:
    return tuple(tuple(float(x) for x in row) for row in np.asarray(m))


def static_motion(up_body: np.ndarray | str) -> Motion:
    """The cube at rest with ``up_body`` (vector or face name like "x_up") pointing up."""
    p = pose(up_body) if isinstance(up_body, str) else pose_from_up(np.asarray(up_body))
    return Motion(_as_tuple(p))


@dataclass(frozen=True)
class TurnMotion(Motion):
    """A hand turn about the vertical starting from ``attitude``, with optional wobble.

    Attitude ``R(t) = W(t) · Rz(ψ(t)) · P``, with ``W = Rx(α)·Ry(β)`` the wobble about the world
    east/north axes. Body rate ``ω = Bᵀ ω_W + Pᵀ ẑ ψ̇`` with ``B = Rz(ψ)·P`` and
    ``ω_W = Ry(β)ᵀ x̂ α̇ + ŷ β̇``.
    """

    profile: TurnProfile = field(default_factory=lambda: TurnProfile((0.0,), (1.0,), (0.0,)))
    wobble: Wobble | None = None

    def kinematics(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=np.float64)
        p = self.pose_matrix
        psi = np.radians(self.profile.angle(t))
        psi_dot = np.radians(self.profile.rate(t))
        b = rot_axis(2, psi) @ p
        omega = psi_dot[..., None] * p[2][None, :]  # Pᵀ ẑ = third row of P
        if self.wobble is None:
            return b, omega
        ang, rate = self.wobble.angles_and_rates(t)
        ry = rot_axis(1, ang[..., 1])
        w = rot_axis(0, ang[..., 0]) @ ry
        # ω_W = Ry(β)ᵀ x̂ α̇ + ŷ β̇ (rate of W in its own frame)
        omega_w = ry[..., 0, :] * rate[..., 0:1]
        omega_w[..., 1] += rate[..., 1]
        omega = omega + np.einsum("...ji,...j->...i", b, omega_w)
        return w @ b, omega

    @property
    def moving(self) -> bool:
        return True


@dataclass(frozen=True)
class ConstantRateMotion(Motion):
    """A rate table turning the cube about the vertical at ``rate_dps`` from ``start_s``."""

    rate_dps: float = 0.0
    start_s: float = 0.0

    def kinematics(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=np.float64)
        p = self.pose_matrix
        psi = np.radians(self.rate_dps) * (t - self.start_s)
        omega = np.broadcast_to(np.radians(self.rate_dps) * p[2], t.shape + (3,)).copy()
        return rot_axis(2, psi) @ p, omega

    @property
    def moving(self) -> bool:
        return True


@dataclass(frozen=True)
class MoveMotion(Motion):
    """A hand moving the unit from ``attitude`` to a new one (no cube: a pose): a rotation by
    ``angle_deg`` about the body axis ``axis`` (unit vector) from ``start_s`` over
    ``duration_s``, its rate a raised cosine (zero at both ends); at rest before and after.
    Attitude ``R(t) = P·Rot(axis, ψ(t))``, body rate ``ψ̇·axis``."""

    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    angle_deg: float = 0.0
    start_s: float = 0.0
    duration_s: float = 1.0

    def _angle_and_rate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        tau = np.clip((t - self.start_s) / self.duration_s, 0.0, 1.0)
        theta = math.radians(self.angle_deg)
        angle = theta * (tau - np.sin(2 * math.pi * tau) / (2 * math.pi))
        rate = theta / self.duration_s * (1.0 - np.cos(2 * math.pi * tau))
        return angle, rate

    def kinematics(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=np.float64)
        angle, rate = self._angle_and_rate(t)
        k = skew(np.array(self.axis))
        s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
        rot = np.eye(3) + s * k + (1.0 - c) * (k @ k)
        return self.pose_matrix @ rot, rate[..., None] * np.array(self.axis)

    @property
    def moving(self) -> bool:
        return True

    @property
    def end_attitude(self) -> np.ndarray:
        """(3, 3) the attitude it comes to rest in."""
        return self.pose_matrix @ rot_vector(np.array(self.axis), math.radians(self.angle_deg))


def move_to(attitude: np.ndarray, up_body: np.ndarray, start_s: float, duration_s: float,
            twist_deg: float = 0.0) -> MoveMotion:  # fmt: skip
    """The move from ``attitude`` (3, 3) that brings gravity along ``up_body`` (unit vector):
    gravity seen in the body turns by Q (Q·u₀ = u₁): the shortest such rotation after a twist of
    ``twist_deg`` about u₀ (a hand does not move along the shortest way), made as one rotation
    about a fixed body axis (Rot(axis, angle) = Qᵀ: a room-fixed vector turns the other way)."""
    u0 = np.asarray(attitude, dtype=np.float64)[2]
    u1 = np.asarray(up_body, dtype=np.float64) / np.linalg.norm(up_body)
    cross = np.cross(u0, u1)
    if np.linalg.norm(cross) < 1e-9:  # the same up (or opposite): about any axis across it
        cross = np.cross(u0, [1.0, 0.0, 0.0] if abs(u0[0]) < 0.9 else [0.0, 1.0, 0.0])
    shortest = rot_vector(cross, math.acos(max(-1.0, min(1.0, float(u0 @ u1)))))
    q = shortest @ rot_vector(u0, math.radians(twist_deg))
    r = q.T
    angle = math.acos(max(-1.0, min(1.0, (float(np.trace(r)) - 1.0) / 2.0)))
    if angle < 1e-9:
        axis = np.array([0.0, 0.0, 1.0])
    elif math.sin(angle) < 1e-3:  # about a half turn: the axis is r's eigenvector of 1
        values, vectors = np.linalg.eig(r)
        axis = np.real(vectors[:, int(np.argmin(np.abs(values - 1.0)))])
        if float(axis @ vee(r - r.T)) < 0:
            axis = -axis
    else:
        axis = vee(r - r.T) / (2.0 * math.sin(angle))
    return MoveMotion(_as_tuple(attitude), (float(axis[0]), float(axis[1]), float(axis[2])),
                      math.degrees(angle), start_s, duration_s)  # fmt: skip


# --------------------------------------------------------------------------- bench
def normal_gravity(latitude_deg: float, height_m: float = 0.0) -> float:
    """Helmert's normal gravity with height correction (method.md §3), m/s²."""
    phi = math.radians(latitude_deg)
    return (
        9.78030 * (1 + 0.005302 * math.sin(phi) ** 2 - 0.000007 * math.sin(2 * phi) ** 2)
        - 0.000003086 * height_m
    )


@dataclass(frozen=True)
class Bench:
    """The bench: place on Earth, heading of the ruler, tilt of the base, hand behaviour.

    ``latitude_deg``/``height_m`` set g (Helmert) and the Earth rate; ``heading_deg`` rotates
    the fixture about the vertical (0: the fixture frame is ENU); ``tilt_deg`` tilts the base
    about the horizontal axis at azimuth ``tilt_azimuth_deg``; ``earth_rate`` switches Earth's
    rotation on/off; ``wobble_deg`` is the largest hand wobble during turns.
    """

    latitude_deg: float = 55.75
    height_m: float = 150.0
    heading_deg: float = 0.0
    tilt_deg: float = 0.0
    tilt_azimuth_deg: float = 0.0
    earth_rate: bool = True
    wobble_deg: float = 0.5

    @property
    def g(self) -> float:
        """Local gravity, m/s²."""
        return normal_gravity(self.latitude_deg, self.height_m)

    @property
    def base(self) -> np.ndarray:
        """Rotation (3, 3) from the fixture frame to the world (tilt · heading)."""
        az = math.radians(self.tilt_azimuth_deg)
        tilt = rot_vector(np.array([math.cos(az), math.sin(az), 0.0]), math.radians(self.tilt_deg))
        return tilt @ rot_axis(2, math.radians(self.heading_deg))

    @property
    def earth_rate_world(self) -> np.ndarray:
        """Earth rate in the world (ENU) frame, °/s (zeros if switched off)."""
        if not self.earth_rate:
            return np.zeros(3)
        phi = math.radians(self.latitude_deg)
        return EARTH_RATE_DPS * np.array([0.0, math.cos(phi), math.sin(phi)])


def body_inputs(
    motion: Motion,
    t: np.ndarray,
    bench: Bench,
    lever_arm_m: np.ndarray | None = None,
    dt_diff: float = 1e-4,
) -> tuple[np.ndarray, np.ndarray]:
    """True specific force (N, 3) m/s² and angular rate (N, 3) °/s in the body frame.

    Specific force ``f = Rᵀ (0, 0, g) + ω̇ × r + ω × (ω × r)`` with ``r`` the lever arm of the
    sensor from the turn axis (body frame, m); rate ``ω + Rᵀ Ω_earth``. ``ω̇`` is a central
    difference of the analytic rate over ``±dt_diff``.
    """
    t = np.asarray(t, dtype=np.float64)
    r_fix, omega = motion.kinematics(t)
    r = bench.base @ r_fix
    up_body = r[..., 2, :]  # Rᵀ ẑ
    f = bench.g * up_body
    if lever_arm_m is not None and np.any(lever_arm_m) and motion.moving:
        arm = np.asarray(lever_arm_m, dtype=np.float64)
        _, om_p = motion.kinematics(t + dt_diff)
        _, om_m = motion.kinematics(t - dt_diff)
        omega_dot = (om_p - om_m) / (2 * dt_diff)
        f = f + np.cross(omega_dot, arm) + np.cross(omega, np.cross(omega, arm))
    rate = np.degrees(omega) + np.einsum("...ji,j->...i", r, bench.earth_rate_world)
    return f, rate


# --------------------------------------------------------------------------- environment
@dataclass(frozen=True)
class Environment:
    """Room, chip warm-up and clocks.

    Chip temperature (°C) at time t since power-on (s):
    ``room_c + rise_c·(1 − exp(−t/tau_s)) + room_amp_c·sin(2π t/room_period_s + room_phase)``.
    With a chamber (``chamber_minutes`` > 0) the air follows a ramp instead of ``room_c``: from
    ``chamber_from_c`` until ``chamber_start_s``, then linearly to ``chamber_to_c`` over
    ``chamber_minutes``, then holds (the chip's own warm-up ``rise_c`` rides on top).
    The sensor's sample clock runs at ``rate_hz·(1 + sample_clock_error)`` (MPU internal
    oscillator, up to ±1 %); the MCU's µs timer gains ``timer_ppm`` parts per million and ticks
    in ``timer_resolution_us`` steps.
    """

    room_c: float = 22.0
    rise_c: float = 12.0
    tau_s: float = 300.0
    room_amp_c: float = 0.3
    room_period_s: float = 2400.0
    room_phase: float = 0.0
    sample_clock_error: float = 0.0
    timer_ppm: float = 0.0
    timer_resolution_us: int = 4
    chamber_from_c: float = 0.0
    chamber_to_c: float = 0.0
    chamber_start_s: float = 0.0
    chamber_minutes: float = 0.0

    def temperature(self, t_s: np.ndarray) -> np.ndarray:
        """Chip temperature, °C, at ``t_s`` seconds since power-on."""
        t = np.asarray(t_s, dtype=np.float64)
        air: np.ndarray | float = self.room_c
        if self.chamber_minutes > 0:
            frac = np.clip((t - self.chamber_start_s) / (60.0 * self.chamber_minutes), 0.0, 1.0)
            air = self.chamber_from_c + (self.chamber_to_c - self.chamber_from_c) * frac
        return (
            air
            + self.rise_c * (1.0 - np.exp(-np.maximum(t, 0.0) / self.tau_s))
            + self.room_amp_c * np.sin(2 * np.pi * t / self.room_period_s + self.room_phase)
        )

    def device_us(self, t_s: np.ndarray) -> np.ndarray:
        """MCU timer reading (int64 µs, not wrapped) at true time ``t_s`` since reset."""
        t = np.asarray(t_s, dtype=np.float64)
        ticks = np.floor(t * 1e6 * (1.0 + self.timer_ppm * 1e-6) / self.timer_resolution_us)
        return ticks.astype(np.int64) * self.timer_resolution_us

    @staticmethod
    def random(rng: np.random.Generator) -> Environment:
        """A plausible room: 19–25 °C, warm-up +8…+15 °C with τ 200–400 s (plateau in
        10–20 min), slow room swing, sample clock within ±1 %, timer within ±50 ppm."""
        return Environment(
            room_c=float(rng.uniform(19.0, 25.0)),
            rise_c=float(rng.uniform(8.0, 15.0)),
            tau_s=float(rng.uniform(200.0, 400.0)),
            room_amp_c=float(rng.uniform(0.1, 0.5)),
            room_period_s=float(rng.uniform(1200.0, 3600.0)),
            room_phase=float(rng.uniform(0, 2 * np.pi)),
            sample_clock_error=float(rng.uniform(-0.01, 0.01)),
            timer_ppm=float(rng.uniform(-50.0, 50.0)),
        )
