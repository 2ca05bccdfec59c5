"""The simulated sensor's truth: every term of the error-model catalogue, and the model itself.

:class:`SensorTruth` holds the method.md §2 linear model under exactly the report's names
(``Axx`` … ``Azx``, ``A0x`` …; ``Gxx`` … ``Gzx``, ``GAxx`` … ``GAzz``, ``G0x`` …) plus the
effects the linear model leaves out. :func:`sensor_output` applies them to true inputs.

Per channel i (accelerometer shown; the gyro is the same in °/s, plus ``GA @ f/g``)::

    A_i = Σ_j M_ij f_j                                  linear model (M = I + scale/misalignment)
        + (s_T,i·ΔT + ½·asym_i·sign(f_i))·f_i           temperature scale, scale asymmetry
        + k_i·f_i²                                      scale nonlinearity
        + A0_i + b1_i·ΔT + b2_i·ΔT² + b3_i·ΔT³ + d_i·t_h  bias, its temperature and time drift
        + w_i(t) + n_i                                  bias instability, white noise

with ΔT = T − ``temp_ref_c`` and t_h hours since power-on. The asymmetry keeps the mean scale:
a positive input sees scale ``1 + Axx + asym/2``, a negative one ``1 + Axx − asym/2``. f and
the rate are along the sensor's axes: on a board mounted in a cube of several
(:mod:`host.bench.cube`), Rot(θ)ᵀ times the cube's (``mounting_rad``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

Vec3 = tuple[float, float, float]
_ZERO3: Vec3 = (0.0, 0.0, 0.0)

ACCEL_SCALE = ("Axx", "Ayy", "Azz")
ACCEL_MISALIGNMENT = ("Axz", "Axy", "Ayz", "Ayx", "Azy", "Azx")
ACCEL_BIAS = ("A0x", "A0y", "A0z")
GYRO_SCALE = ("Gxx", "Gyy", "Gzz")
GYRO_MISALIGNMENT = ("Gxz", "Gxy", "Gyz", "Gyx", "Gzy", "Gzx")
GYRO_G_SENSITIVITY = tuple(f"GA{a}{b}" for a in "xyz" for b in "xyz")
GYRO_BIAS = ("G0x", "G0y", "G0z")
#: the report's constants (method.md §2, §7), in report order
CONSTANT_NAMES = (
    GYRO_SCALE
    + GYRO_MISALIGNMENT
    + GYRO_BIAS
    + GYRO_G_SENSITIVITY
    + ACCEL_SCALE
    + ACCEL_MISALIGNMENT
    + ACCEL_BIAS
)

#: effect name -> the fields it consists of (every field belongs to exactly one effect)
EFFECTS: dict[str, tuple[str, ...]] = {
    "scale": ACCEL_SCALE + GYRO_SCALE,
    "misalignment": ACCEL_MISALIGNMENT + GYRO_MISALIGNMENT,
    "bias": ACCEL_BIAS + GYRO_BIAS,
    "g_sensitivity": GYRO_G_SENSITIVITY,
    "temperature_bias": (
        "accel_temp_bias",
        "accel_temp_bias2",
        "gyro_temp_bias",
        "gyro_temp_bias2",
        "accel_temp_bias3",
        "gyro_temp_bias3",
    ),
    "temperature_scale": ("accel_temp_scale", "gyro_temp_scale"),
    "time_drift": ("accel_drift", "gyro_drift"),
    "scale_asymmetry": ("accel_scale_asym", "gyro_scale_asym"),
    "nonlinearity": ("accel_nonlin", "gyro_nonlin"),
    "lever_arm": ("lever_arm_m",),
    "mounting": ("mounting_rad",),
    "noise": ("accel_noise", "gyro_noise"),
    "bias_instability": ("accel_bias_instability", "gyro_bias_instability"),
}
#: shorthand: the whole method.md §2 linear model (without noise)
EFFECT_GROUPS: dict[str, tuple[str, ...]] = {
    "linear": ("scale", "misalignment", "bias", "g_sensitivity"),
}


@dataclass(frozen=True)
class SensorTruth:
    """Every error term of the simulated MPU-6000 (units in the field comments)."""

    # accelerometer, method.md §2: relative scale errors, misalignments (rad), biases (m/s²)
    Axx: float = 0.0
    Ayy: float = 0.0
    Azz: float = 0.0
    Axz: float = 0.0
    Axy: float = 0.0
    Ayz: float = 0.0
    Ayx: float = 0.0
    Azy: float = 0.0
    Azx: float = 0.0
    A0x: float = 0.0
    A0y: float = 0.0
    A0z: float = 0.0
    # gyro: relative scale errors, misalignments (rad), g-sensitivity ((°/s)/g), biases (°/s)
    Gxx: float = 0.0
    Gyy: float = 0.0
    Gzz: float = 0.0
    Gxz: float = 0.0
    Gxy: float = 0.0
    Gyz: float = 0.0
    Gyx: float = 0.0
    Gzy: float = 0.0
    Gzx: float = 0.0
    GAxx: float = 0.0
    GAxy: float = 0.0
    GAxz: float = 0.0
    GAyx: float = 0.0
    GAyy: float = 0.0
    GAyz: float = 0.0
    GAzx: float = 0.0
    GAzy: float = 0.0
    GAzz: float = 0.0
    G0x: float = 0.0
    G0y: float = 0.0
    G0z: float = 0.0
    # beyond the linear model, per channel x, y, z
    temp_ref_c: float = 25.0  #: °C at which the constants above hold
    accel_temp_bias: Vec3 = _ZERO3  #: m/s² per °C
    accel_temp_bias2: Vec3 = _ZERO3  #: m/s² per °C²
    gyro_temp_bias: Vec3 = _ZERO3  #: °/s per °C
    gyro_temp_bias2: Vec3 = _ZERO3  #: °/s per °C²
    accel_temp_bias3: Vec3 = _ZERO3  #: m/s² per °C³ (not drawn by :meth:`random`)
    gyro_temp_bias3: Vec3 = _ZERO3  #: °/s per °C³ (not drawn by :meth:`random`)
    accel_temp_scale: Vec3 = _ZERO3  #: relative scale per °C
    gyro_temp_scale: Vec3 = _ZERO3  #: relative scale per °C
    accel_drift: Vec3 = _ZERO3  #: m/s² per hour since power-on
    gyro_drift: Vec3 = _ZERO3  #: °/s per hour since power-on
    accel_scale_asym: Vec3 = _ZERO3  #: scale(positive input) − scale(negative input)
    gyro_scale_asym: Vec3 = _ZERO3  #: same for the gyro
    accel_nonlin: Vec3 = _ZERO3  #: 1/(m/s²): adds k·f² (m/s²)
    gyro_nonlin: Vec3 = _ZERO3  #: 1/(°/s): adds k·ω² (°/s)
    lever_arm_m: Vec3 = _ZERO3  #: sensor position from the turn axis, body frame, m
    #: the board's mounting in a cube of several (:mod:`host.bench.cube`): the rotation vector
    #: (rad) turning the cube's axes into the sensor's (v_cube = Rot(θ)·v_sensor); zero on a
    #: bench of one board (not drawn by :meth:`random`)
    mounting_rad: Vec3 = _ZERO3
    accel_noise: Vec3 = _ZERO3  #: white noise, std per sample, m/s²
    gyro_noise: Vec3 = _ZERO3  #: white noise, std per sample, °/s
    accel_bias_instability: Vec3 = _ZERO3  #: Gauss-Markov bias, steady-state std, m/s²
    gyro_bias_instability: Vec3 = _ZERO3  #: Gauss-Markov bias, steady-state std, °/s
    bias_corr_time_s: float = 300.0  #: correlation time of the Gauss-Markov bias, s

    # ---- construction ------------------------------------------------------------------
    @staticmethod
    def ideal() -> SensorTruth:
        """A perfect sensor: every term zero (output = quantised truth)."""
        return SensorTruth()

    @staticmethod
    def random(rng: np.random.Generator) -> SensorTruth:
        """Draw every term within realistic bounds (method.md §7's real report, datasheet).

        Gyro scale ±0.02, misalignment ±0.01, bias ±3 °/s, g-sensitivity ±0.05 (°/s)/g;
        accel scale ±0.015, misalignment ±0.01, bias ±0.3 m/s²; noise 0.008–0.011 m/s² and
        0.021–0.026 °/s per sample.
        """

        def u(lim: float, n: int = 3) -> tuple[float, ...]:
            return tuple(float(x) for x in rng.uniform(-lim, lim, n))

        def v3(lo: float, hi: float) -> Vec3:
            a = rng.uniform(lo, hi, 3)
            return (float(a[0]), float(a[1]), float(a[2]))

        def s3(lim: float) -> Vec3:
            a = rng.uniform(-lim, lim, 3)
            return (float(a[0]), float(a[1]), float(a[2]))

        vals: dict[str, float] = {}
        for names, lim in (
            (ACCEL_SCALE, 0.015),
            (ACCEL_MISALIGNMENT, 0.01),
            (ACCEL_BIAS, 0.3),
            (GYRO_SCALE, 0.02),
            (GYRO_MISALIGNMENT, 0.01),
            (GYRO_G_SENSITIVITY, 0.05),
            (GYRO_BIAS, 3.0),
        ):
            vals.update(zip(names, u(lim, len(names)), strict=True))
        return SensorTruth(
            **vals,
            accel_temp_bias=s3(0.003),
            accel_temp_bias2=s3(5e-5),
            gyro_temp_bias=s3(0.03),
            gyro_temp_bias2=s3(3e-4),
            accel_temp_bias3=_ZERO3,
            gyro_temp_bias3=_ZERO3,
            accel_temp_scale=s3(2e-4),
            gyro_temp_scale=s3(2e-4),
            accel_drift=s3(0.002),
            gyro_drift=s3(0.02),
            accel_scale_asym=s3(0.002),
            gyro_scale_asym=s3(0.002),
            accel_nonlin=s3(1e-4),
            gyro_nonlin=s3(4e-6),
            lever_arm_m=s3(0.03),
            mounting_rad=_ZERO3,
            accel_noise=v3(0.008, 0.011),
            gyro_noise=v3(0.021, 0.026),
            accel_bias_instability=v3(2e-4, 8e-4),
            gyro_bias_instability=v3(0.002, 0.006),
        )

    def only(self, *effects: str) -> SensorTruth:
        """A copy keeping only the named effects (see :data:`EFFECTS`, or "linear"); every
        other term is zero. E.g. ``truth.only("temperature_bias")``."""
        keep = set(_fields_of(effects))
        return dataclasses.replace(
            self, **{f: _zero_like(getattr(self, f)) for f in _all_effect_fields() if f not in keep}
        )

    def without(self, *effects: str) -> SensorTruth:
        """A copy with the named effects zeroed."""
        return dataclasses.replace(
            self, **{f: _zero_like(getattr(self, f)) for f in _fields_of(effects)}
        )

    # ---- views -------------------------------------------------------------------------
    def constants(self) -> dict[str, float]:
        """The report's constants (method.md §7 names) -> value, referred to the cube's axes
        as a calibration finds them: with a mounting (:attr:`mounting_rad`) the matrices are
        the sensor's times Rot(θ)ᵀ (M_A·Rᵀ, M_G·Rᵀ, GA·Rᵀ), read back into the names."""
        out = {name: float(getattr(self, name)) for name in CONSTANT_NAMES}
        if any(self.mounting_rad):
            r_t = self.mounting.T
            out.update(_matrix_constants("A", self.accel_matrix @ r_t))
            out.update(_matrix_constants("G", self.gyro_matrix @ r_t))
            ga = self.g_sensitivity @ r_t
            out.update({f"GA{a}{b}": float(ga[i, j]) for i, a in enumerate("xyz")
                        for j, b in enumerate("xyz")})  # fmt: skip
        return out

    def constants_at(self, temp_c: float, hours_since_power_on: float = 0.0) -> dict[str, float]:
        """The report's constants as a linear calibration at chip temperature ``temp_c`` °C and
        ``hours_since_power_on`` h would see them: biases plus their temperature terms and
        time drift, scale errors plus their temperature terms (asymmetry, nonlinearity, noise
        and the lever arm are left out). ``constants()`` holds at ``temp_ref_c`` and hour 0."""
        d = temp_c - self.temp_ref_c
        h = hours_since_power_on
        out = self.constants()
        for i, a in enumerate("xyz"):
            out[f"A0{a}"] += (
                self.accel_temp_bias[i] * d
                + self.accel_temp_bias2[i] * d * d
                + self.accel_temp_bias3[i] * d**3
                + self.accel_drift[i] * h
            )
            out[f"G0{a}"] += (
                self.gyro_temp_bias[i] * d
                + self.gyro_temp_bias2[i] * d * d
                + self.gyro_temp_bias3[i] * d**3
                + self.gyro_drift[i] * h
            )
            out[f"A{a}{a}"] += self.accel_temp_scale[i] * d
            out[f"G{a}{a}"] += self.gyro_temp_scale[i] * d
        return out

    @property
    def accel_matrix(self) -> np.ndarray:
        """M_A (3, 3): accel output = M_A @ f + ... (method.md §2)."""
        return np.array(
            [
                [1 + self.Axx, self.Axz, -self.Axy],
                [-self.Ayz, 1 + self.Ayy, self.Ayx],
                [self.Azy, -self.Azx, 1 + self.Azz],
            ]
        )

    @property
    def gyro_matrix(self) -> np.ndarray:
        """M_G (3, 3): gyro output = M_G @ ω + GA @ f/g + ... (method.md §2)."""
        return np.array(
            [
                [1 + self.Gxx, self.Gxz, -self.Gxy],
                [-self.Gyz, 1 + self.Gyy, self.Gyx],
                [self.Gzy, -self.Gzx, 1 + self.Gzz],
            ]
        )

    @property
    def mounting(self) -> np.ndarray:
        """Rot(θ) (3, 3) of :attr:`mounting_rad`: v_cube = Rot(θ) @ v_sensor (I without one)."""
        theta = np.asarray(self.mounting_rad, dtype=np.float64)
        angle = float(np.linalg.norm(theta))
        if angle == 0.0:
            return np.eye(3)
        k = theta / angle
        kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        return np.eye(3) + np.sin(angle) * kx + (1.0 - np.cos(angle)) * (kx @ kx)

    @property
    def g_sensitivity(self) -> np.ndarray:
        """GA (3, 3), (°/s)/g: row = gyro channel, column = specific-force axis."""
        return np.array([[getattr(self, f"GA{a}{b}") for b in "xyz"] for a in "xyz"])

    @property
    def accel_bias(self) -> np.ndarray:
        return np.array([self.A0x, self.A0y, self.A0z])

    @property
    def gyro_bias(self) -> np.ndarray:
        return np.array([self.G0x, self.G0y, self.G0z])


def _all_effect_fields() -> list[str]:
    return [f for fs in EFFECTS.values() for f in fs]


def _fields_of(effects: tuple[str, ...]) -> list[str]:
    out: list[str] = []
    for e in effects:
        if e in EFFECT_GROUPS:
            out += _fields_of(EFFECT_GROUPS[e])
        elif e in EFFECTS:
            out += list(EFFECTS[e])
        else:
            known = ", ".join(sorted(EFFECTS) + sorted(EFFECT_GROUPS))
            raise ValueError(f"unknown effect {e!r}; known: {known}")
    return out


def _zero_like(v: object) -> Any:
    return _ZERO3 if isinstance(v, tuple) else 0.0


def _matrix_constants(prefix: str, m: np.ndarray) -> dict[str, float]:
    """The scale and misalignment names of matrix ``m`` (``accel_matrix``'s layout), ``prefix``
    A or G."""
    p = prefix
    return {
        f"{p}xx": float(m[0, 0] - 1.0), f"{p}yy": float(m[1, 1] - 1.0),
        f"{p}zz": float(m[2, 2] - 1.0), f"{p}xz": float(m[0, 1]), f"{p}xy": float(-m[0, 2]),
        f"{p}yz": float(-m[1, 0]), f"{p}yx": float(m[1, 2]), f"{p}zy": float(m[2, 0]),
        f"{p}zx": float(-m[2, 1]),
    }  # fmt: skip


# --------------------------------------------------------------------------- the model
def _channel_terms(
    x: np.ndarray,
    d_temp: np.ndarray,
    t_h: np.ndarray,
    temp_scale: Vec3,
    asym: Vec3,
    nonlin: Vec3,
    temp_bias: Vec3,
    temp_bias2: Vec3,
    drift: Vec3,
) -> np.ndarray:
    """Per-channel terms beyond the linear model, (N, 3), in the channel's units."""
    dt = d_temp[:, None]
    scale = np.asarray(temp_scale) * dt + 0.5 * np.asarray(asym) * np.sign(x)
    return (
        scale * x
        + np.asarray(nonlin) * x * x
        + np.asarray(temp_bias) * dt
        + np.asarray(temp_bias2) * dt * dt
        + np.asarray(drift) * t_h[:, None]
    )


def sensor_output(
    truth: SensorTruth,
    specific_force: np.ndarray,
    rate_dps: np.ndarray,
    temp_c: np.ndarray,
    t_since_power_on_s: np.ndarray,
    g: float,
    accel_disturbance: np.ndarray | None = None,
    gyro_disturbance: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """What the sensor outputs (m/s², °/s; before quantisation) for true inputs.

    ``specific_force`` (N, 3) m/s², ``rate_dps`` (N, 3) °/s, ``temp_c`` (N,) chip °C,
    ``t_since_power_on_s`` (N,), ``g`` local gravity m/s² (g-sensitivity is per g of specific
    force). ``*_disturbance`` (N, 3): noise + bias instability to add (already scaled). The
    inputs are along the cube's axes; a mounting (:attr:`SensorTruth.mounting_rad`) turns them
    into the sensor's first.
    """
    f = np.asarray(specific_force, dtype=np.float64)
    w = np.asarray(rate_dps, dtype=np.float64)
    if any(truth.mounting_rad):  # cube axes -> the sensor's: v_sensor = Rot(θ)ᵀ v_cube
        f, w = f @ truth.mounting, w @ truth.mounting
    d_temp = np.asarray(temp_c, dtype=np.float64) - truth.temp_ref_c
    t_h = np.asarray(t_since_power_on_s, dtype=np.float64) / 3600.0
    accel = f @ truth.accel_matrix.T + truth.accel_bias
    accel += _channel_terms(
        f,
        d_temp,
        t_h,
        truth.accel_temp_scale,
        truth.accel_scale_asym,
        truth.accel_nonlin,
        truth.accel_temp_bias,
        truth.accel_temp_bias2,
        truth.accel_drift,
    )
    gyro = w @ truth.gyro_matrix.T + (f / g) @ truth.g_sensitivity.T + truth.gyro_bias
    gyro += _channel_terms(
        w,
        d_temp,
        t_h,
        truth.gyro_temp_scale,
        truth.gyro_scale_asym,
        truth.gyro_nonlin,
        truth.gyro_temp_bias,
        truth.gyro_temp_bias2,
        truth.gyro_drift,
    )
    cube = d_temp[:, None] ** 3
    accel += np.asarray(truth.accel_temp_bias3) * cube
    gyro += np.asarray(truth.gyro_temp_bias3) * cube
    if accel_disturbance is not None:
        accel += accel_disturbance
    if gyro_disturbance is not None:
        gyro += gyro_disturbance
    return accel, gyro


def gauss_markov(
    rng: np.random.Generator, x0: np.ndarray, n: int, dt: float, tau: float, sigma: np.ndarray
) -> np.ndarray:
    """First-order Gauss-Markov process, (n, k): steady-state std ``sigma`` (k,), correlation
    time ``tau`` s, step ``dt`` s, starting one step after state ``x0`` (k,)."""
    sigma = np.asarray(sigma, dtype=np.float64)
    x0 = np.asarray(x0, dtype=np.float64)
    e = rng.standard_normal((n, x0.shape[0]))
    if n == 0 or not np.any(sigma):
        return np.zeros((n, x0.shape[0]))
    phi = float(np.exp(-dt / tau))
    drive = sigma * np.sqrt(1.0 - phi * phi)
    out = np.empty((n, x0.shape[0]))
    # closed form per block: x_k = φ^k x0 + Σ_j φ^(k−j) drive e_j, in blocks keeping φ^-k finite
    block = max(1, min(n, int(20.0 * tau / dt) if dt > 0 else n))
    x = x0
    for s in range(0, n, block):
        m = min(block, n - s)
        k = np.arange(1, m + 1)[:, None]
        pw = phi**k
        acc = np.cumsum(e[s : s + m] * drive / pw, axis=0)
        out[s : s + m] = pw * (x + acc)
        x = out[s + m - 1]
    return out
