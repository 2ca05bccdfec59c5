"""First-principles physics of a cube on a plate, written apart from ``host/bench/``.

Frames. The room: e (east, along the fence/ruler), n (north), u (up, against gravity); a resting
accelerometer reads the specific force +g·u. The plate's normal p may lean from u (plate tilt).
The body: the sensor's axes x, y, z. A placement puts the body direction ``seat`` (the face's
outward normal seen from the sensor, nominally a signed body axis) along the plate's normal and
the body's *reference axis* (the first of x, y, z, positive, not along the up axis) at heading
ψ, counter-clockwise from the plate's east seen from above. A hand turn adds a rotation about
the plate's normal to ψ.

Units: metres, seconds, radians inside; gyro outputs °/s; specific force m/s².
Nothing here is imported from the project's own simulator or model: the tests use this module
as an independent witness.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: sample rate, Hz (MPU-6000 output read by the APM at about 50 Hz)
FS_HZ = 50.0
#: MPU-6000 at ±2 g: 16-bit counts over 4 g (method.md §1)
ACCEL_LSB = 4.0 * 9.81 / 2**16
#: MPU-6000 at ±250 °/s: 16-bit counts over 500 °/s
GYRO_LSB = 500.0 / 2**16
#: chip temperature: counts/340 + 36.53 °C (MPU-6000 register map)
TEMP_LSB = 1.0 / 340.0
TEMP_OFFSET_C = 36.53
INT16 = (-32768, 32767)
AXES = "xyz"


def local_g(latitude_deg: float = 55.75, height_m: float = 150.0) -> float:
    """Helmert's normal gravity with the height term (method.md §3), m/s²."""
    phi = math.radians(latitude_deg)
    return (
        9.78030 * (1 + 0.005302 * math.sin(phi) ** 2 - 0.000007 * math.sin(2 * phi) ** 2)
        - 0.000003086 * height_m
    )


def axis_vector(spec: str) -> np.ndarray:
    """'+x' / '-z' / 'y' -> unit vector in body axes."""
    v = np.zeros(3)
    v[AXES.index(spec[-1])] = -1.0 if spec.startswith("-") else 1.0
    return v


def reference_axis(up: np.ndarray) -> np.ndarray:
    """The first body axis (x, y, z order, positive) that is not along ``up`` (not parallel
    to it: for a 45° attitude with x up at 45°, +x, made level)."""
    u = np.asarray(up, dtype=float) / np.linalg.norm(up)
    k = next(i for i in range(3) if abs(u[i]) < 1.0 - 1e-9)
    return axis_vector("+" + AXES[k])


def rot_about(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """Rotation matrix (Rodrigues) turning vectors by ``angle_rad`` about unit ``axis``."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle_rad) * k + (1 - math.cos(angle_rad)) * (k @ k)


def seat_direction(up: np.ndarray, lean_rad: np.ndarray) -> np.ndarray:
    """The body direction that ends up along the plate's normal: the nominal ``up`` axis leaned
    by ``lean_rad`` (3,) (its component along ``up`` ignored): gravity then has a component
    ``+g·lean_i`` on the horizontal accelerometer i."""
    d = up + np.asarray(lean_rad, dtype=float) * (1.0 - np.abs(up))
    return d / np.linalg.norm(d)


def placement(seat: np.ndarray, ref: np.ndarray, heading_rad: float) -> np.ndarray:
    """Body -> plate rotation of a cube resting with body ``seat`` along the plate's normal and
    body ``ref`` (made perpendicular to ``seat``) at heading ``heading_rad`` from the plate's
    east (counter-clockwise seen from above)."""
    s = seat / np.linalg.norm(seat)
    h = ref - (ref @ s) * s
    h /= np.linalg.norm(h)
    body = np.column_stack([s, h, np.cross(s, h)])
    hp = np.array([math.cos(heading_rad), math.sin(heading_rad), 0.0])
    plate = np.column_stack([np.array([0.0, 0.0, 1.0]), hp, np.cross([0.0, 0.0, 1.0], hp)])
    return plate @ body.T


def plate_to_room(tilt_rad: float, azimuth_rad: float) -> np.ndarray:
    """Plate -> room rotation of a plate whose normal leans ``tilt_rad`` toward the room
    azimuth ``azimuth_rad`` (counter-clockwise from east)."""
    if tilt_rad == 0.0:
        return np.eye(3)
    axis = np.array([-math.sin(azimuth_rad), math.cos(azimuth_rad), 0.0])
    return rot_about(axis, tilt_rad)


@dataclass(frozen=True)
class TurnProfile:
    """A hand turn of ``n`` whole turns as quarter turns with rests: the rate about the plate's
    normal is A_k·sin²(π·τ/T_k) within quarter k (each exactly 90°), zero at the rests.

    ``starts`` (4n,) s from the record's start, ``durations`` (4n,) s, ``sign`` +1 ccw, −1 cw;
    ``scale``: the hand turns every quarter this many times 90° (1: exact; 1 + e/(360·n): a
    turn e° long)."""

    starts: np.ndarray
    durations: np.ndarray
    sign: int
    scale: float = 1.0

    def angle_deg(self, t: np.ndarray) -> np.ndarray:
        """Turned angle (signed, °) at record times ``t`` (s)."""
        out = np.zeros_like(t, dtype=float)
        for t0, d in zip(self.starts, self.durations, strict=True):
            tau = np.clip(t - t0, 0.0, d)
            out += 90.0 * (tau / d - np.sin(2 * math.pi * tau / d) / (2 * math.pi))
        return self.sign * self.scale * out

    def rate_dps(self, t: np.ndarray) -> np.ndarray:
        """Rate about the plate's normal, °/s."""
        out = np.zeros_like(t, dtype=float)
        for t0, d in zip(self.starts, self.durations, strict=True):
            inside = (t >= t0) & (t <= t0 + d)
            out[inside] += (180.0 / d) * np.sin(math.pi * (t[inside] - t0) / d) ** 2
        return self.sign * self.scale * out

    def accel_dps2(self, t: np.ndarray) -> np.ndarray:
        """Angular acceleration about the plate's normal, °/s²."""
        out = np.zeros_like(t, dtype=float)
        for t0, d in zip(self.starts, self.durations, strict=True):
            inside = (t >= t0) & (t <= t0 + d)
            out[inside] += (180.0 / d) * (math.pi / d) * np.sin(2 * math.pi * (t[inside] - t0) / d)
        return self.sign * self.scale * out


def hand_turn(
    rng: np.random.Generator, turns: int, window_s: float, sign: int, quarter_s: float = 0.95
) -> TurnProfile:
    """Quarter turns of about ``quarter_s`` s (±10 %), a rest of 0.7–0.9 s before the first,
    0.3–0.5 s between them and the rest of ``window_s`` after the last (at least 0.4 s)."""
    q = 4 * turns
    dur = quarter_s * rng.uniform(0.9, 1.1, q)
    rests = rng.uniform(0.3, 0.5, q - 1)
    first = rng.uniform(0.7, 0.9)
    total = first + dur.sum() + rests.sum()
    if total > window_s - 0.4:
        shrink = (window_s - 0.4 - first) / (dur.sum() + rests.sum())
        dur, rests = dur * shrink, rests * shrink
    starts = first + np.concatenate([[0.0], np.cumsum(dur[:-1] + rests)])
    return TurnProfile(starts=starts, durations=dur, sign=sign)


@dataclass(frozen=True)
class ContinuousTurn:
    """A hand turn of ``n`` whole turns in ONE motion (the method's bench: rests only at its
    start and end, the same heading): from ``start`` s for ``duration`` s the rate about the
    plate's normal is A·sin²(πu)·(1 + a·sin(2πmu + φ)), u = (t − start)/duration, A = 720°·n
    /duration (the hand speeding up and slowing down ``m`` ≥ 2 times, by ±``a`` < 1: the
    modulation integrates to 0 over the turn, so the turned angle is exactly 360°·n), zero
    outside. ``sign`` +1 ccw, −1 cw; ``scale`` as :class:`TurnProfile`'s."""

    start: float
    duration: float
    turns: int
    sign: int
    depth: float = 0.0
    waves: int = 2
    phase: float = 0.0
    scale: float = 1.0

    def _u(self, t: np.ndarray) -> np.ndarray:
        return np.clip((np.asarray(t, dtype=float) - self.start) / self.duration, 0.0, 1.0)

    @property
    def _peak(self) -> float:
        return 720.0 * self.turns / self.duration

    def angle_deg(self, t: np.ndarray) -> np.ndarray:
        """Turned angle (signed, °) at record times ``t`` (s): the rate's integral in closed
        form (∫ sin(2πkv + φ) dv = (cos φ − cos(2πku + φ))/(2πk), k ≥ 1)."""
        u, m, ph = self._u(t), self.waves, self.phase

        def s_int(k: int) -> np.ndarray:
            return (math.cos(ph) - np.cos(2 * math.pi * k * u + ph)) / (2 * math.pi * k)

        base = u / 2 - np.sin(2 * math.pi * u) / (4 * math.pi)
        mod = 0.5 * s_int(m) - 0.25 * (s_int(m + 1) + s_int(m - 1))
        return self.sign * self.scale * self._peak * self.duration * (base + self.depth * mod)

    def rate_dps(self, t: np.ndarray) -> np.ndarray:
        """Rate about the plate's normal, °/s."""
        u = self._u(t)
        wave = 1.0 + self.depth * np.sin(2 * math.pi * self.waves * u + self.phase)
        inside = (u > 0.0) & (u < 1.0)
        return np.where(inside, self.sign * self.scale * self._peak * np.sin(math.pi * u) ** 2
                        * wave, 0.0)  # fmt: skip

    def accel_dps2(self, t: np.ndarray) -> np.ndarray:
        """Angular acceleration about the plate's normal, °/s²."""
        u, m, ph = self._u(t), self.waves, self.phase
        wave = 1.0 + self.depth * np.sin(2 * math.pi * m * u + ph)
        d_wave = self.depth * 2 * math.pi * m * np.cos(2 * math.pi * m * u + ph)
        d = math.pi * np.sin(2 * math.pi * u) * wave + np.sin(math.pi * u) ** 2 * d_wave
        inside = (u > 0.0) & (u < 1.0)
        return np.where(inside, self.sign * self.scale * self._peak * d / self.duration, 0.0)


def continuous_turn(
    rng: np.random.Generator, turns: int, window_s: float, sign: int, turn_s: float = 4.4
) -> ContinuousTurn:
    """``turns`` whole turns in one motion of about ``turn_s`` s per turn (±10 %), after a
    rest of 0.7–0.9 s, the rest of ``window_s`` after it (at least 0.4 s); the hand speeds
    up and slows down 2–3 times by ±10–25 % (peak below 230 °/s at the hand's pace)."""
    first = rng.uniform(0.7, 0.9)
    dur = min(turns * turn_s * rng.uniform(0.9, 1.1), window_s - 0.4 - first)
    depth, waves, phase = rng.uniform(0.1, 0.25), int(rng.integers(2, 4)), rng.uniform(0, 6.283)
    return ContinuousTurn(first, dur, turns, sign, depth, waves, phase)


def error_matrix(scale: np.ndarray, mis: dict[str, float], sensor: str) -> np.ndarray:
    """I + M of method.md §2: row i of the output, column j of the input, with the signs of §2:
    x row (1+Sxx, Sxz, −Sxy), y row (−Syz, 1+Syy, Syx), z row (Szy, −Szx, 1+Szz); ``mis`` keys
    'xz', 'xy', 'yz', 'yx', 'zy', 'zx'; ``sensor`` only names the matrix."""
    del sensor
    return np.array(
        [
            [1 + scale[0], mis["xz"], -mis["xy"]],
            [-mis["yz"], 1 + scale[1], mis["yx"]],
            [mis["zy"], -mis["zx"], 1 + scale[2]],
        ]
    )


def quantise(values: np.ndarray, lsb: float) -> np.ndarray:
    """Round to whole counts of ``lsb``, clipped to the int16 range, back in the unit."""
    counts = np.clip(np.round(values / lsb), *INT16)
    return counts * lsb


def white_noise(rng: np.random.Generator, density: float, shape: tuple[int, ...]) -> np.ndarray:
    """White noise of one-sided density ``density`` (unit/√Hz) sampled at :data:`FS_HZ`:
    per-sample std = density·√(FS/2)."""
    return rng.normal(0.0, density * math.sqrt(FS_HZ / 2.0), shape)


def chip_temperature(power_on_s: np.ndarray, temp: TempModel) -> tuple[np.ndarray, np.ndarray]:
    """(T °C, dT/dt °C/s) at times since power-on: a warm-up toward ``ambient + rise`` with time
    constant ``tau_s`` plus a slow room swing ``swing_c``·sin(2π t/``period_s`` + phase)."""
    t = np.asarray(power_on_s, dtype=float)
    w = 2 * math.pi / temp.period_s
    temp_c = (
        temp.ambient_c
        + temp.rise_c * (1 - np.exp(-t / temp.tau_s))
        + temp.swing_c * np.sin(w * t + temp.phase)
    )
    rate = temp.rise_c / temp.tau_s * np.exp(-t / temp.tau_s) + temp.swing_c * w * np.cos(
        w * t + temp.phase
    )
    return temp_c, rate


@dataclass(frozen=True)
class TempModel:
    """Chip temperature over the sitting (see :func:`chip_temperature`)."""

    ambient_c: float = 22.0
    rise_c: float = 9.0
    tau_s: float = 500.0
    swing_c: float = 0.4
    period_s: float = 420.0
    phase: float = 0.0
