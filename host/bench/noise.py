"""Long static recordings with a known noise model, for the Allan-deviation tools.

Per channel (unit: m/s² or °/s) the output is white noise of density ``N`` (unit/√Hz), bias
instability ``B`` (flicker noise: one-sided power spectral density B²/(π·f), whose Allan
deviation is flat at 0.664·B, IEEE Std 952 Annex C), and rate random walk ``K`` (unit/s/√Hz:
the integral of white noise of density K), plus an optional bias that follows the chip
temperature (``temp_coef``, unit/°C) of :class:`host.bench.physics.Environment`. Pure numpy;
draws only from the given generator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from host.bench.physics import Environment, pose
from host.wire import sensor


@dataclass(frozen=True)
class NoiseTruth:
    """Known noise of the six channels ax, ay, az (m/s²), gx, gy, gz (°/s): ``white`` N
    (unit/√Hz), ``flicker`` B (unit), ``random_walk`` K (unit/s/√Hz), ``temp_coef``
    (unit/°C, bias against chip temperature), each (6,)."""

    white: tuple[float, ...]
    flicker: tuple[float, ...]
    random_walk: tuple[float, ...]
    temp_coef: tuple[float, ...] = (0.0,) * 6

    @staticmethod
    def mpu6000() -> NoiseTruth:
        """Figures of the MPU-6000's order (datasheet: gyro 0.005 °/s/√Hz, accel 400 µg/√Hz),
        a different value on every channel, with a bias instability and a random walk strong
        enough to show within hours."""
        return NoiseTruth(
            white=(0.0030, 0.0034, 0.0040, 0.0031, 0.0036, 0.0042),
            flicker=(0.0012, 0.0014, 0.0017, 0.0015, 0.0020, 0.0025),
            random_walk=(6e-5, 7e-5, 9e-5, 1.0e-4, 1.3e-4, 1.6e-4),
        )


def flicker_noise(rng: np.random.Generator, n: int, rate_hz: float, b: float) -> np.ndarray:
    """(n,) samples of flicker noise with one-sided PSD b²/(π·f) (Allan deviation 0.664·b),
    shaped in the frequency domain over the whole length."""
    if b == 0 or n == 0:
        return np.zeros(n)
    f = np.fft.rfftfreq(n, 1.0 / rate_hz)
    psd = np.zeros_like(f)
    psd[1:] = b * b / (np.pi * f[1:])
    spec = np.sqrt(psd * rate_hz * n / 4.0) * (
        rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)
    )
    return np.fft.irfft(spec, n)


def static_noise(
    truth: NoiseTruth,
    duration_s: float,
    rng: np.random.Generator,
    rate_hz: float = 50.0,
    environment: Environment | None = None,
    face: str = "z_up",
    g: float = 9.80665,
    power_on_s: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A static recording on ``face``: times (n,) s, channels (n, 6) ax..gz in m/s² and °/s
    quantised to the MPU-6000's LSB (±2 g, ±250 °/s), chip temperature (n,) °C
    (``environment`` since ``power_on_s``; a constant 25 °C when None)."""
    n = int(round(duration_s * rate_hz))
    t = np.arange(n) / rate_hz
    up = pose(face)[2]
    clean = np.concatenate([g * up, np.zeros(3)])
    temp = np.full(n, 25.0) if environment is None else environment.temperature(t + power_on_s)
    out = np.empty((n, 6))
    for j in range(6):
        x = truth.white[j] * np.sqrt(rate_hz) * rng.standard_normal(n)
        x += flicker_noise(rng, n, rate_hz, truth.flicker[j])
        if truth.random_walk[j]:
            x += np.cumsum(truth.random_walk[j] / np.sqrt(rate_hz) * rng.standard_normal(n))
        x += truth.temp_coef[j] * (temp - temp[0]) + clean[j]
        out[:, j] = x
    counts = np.column_stack([sensor.accel_counts(out[:, :3]), sensor.gyro_counts(out[:, 3:])])
    quant = np.column_stack([sensor.accel_mps2(counts[:, :3]), sensor.gyro_dps(counts[:, 3:])])
    return t, quant, sensor.temp_c(sensor.temp_counts(temp))


def capture_bytes(t_s: np.ndarray, data: np.ndarray, temp_c: np.ndarray) -> bytes:
    """An IMUCAP01 capture of IMU_SAMPLE frames carrying the recording of
    :func:`static_noise` (times s, channels ax..gz m/s² and °/s, temperature °C), one read per
    second of samples with host times equal to the device times."""
    from host.wire.capture import MAGIC
    from host.wire.frames import encode_imu_samples
    from host.wire.resync import REC

    counts = np.column_stack(
        [
            sensor.accel_counts(data[:, :3]),
            sensor.temp_counts(temp_c),
            sensor.gyro_counts(data[:, 3:]),
        ]
    )
    t_us = np.rint(np.asarray(t_s) * 1e6).astype(np.int64)
    rate = max(1, int(round(1.0 / float(np.median(np.diff(t_s))))))
    parts = [MAGIC]
    for s in range(0, t_us.size, rate):
        chunk = encode_imu_samples(s & 0xFFFF, t_us[s : s + rate], counts[s : s + rate])
        parts.append(REC.pack(int(t_us[min(s + rate, t_us.size) - 1]) * 1000, len(chunk)))
        parts.append(chunk)
    return b"".join(parts)


def main(argv: list[str] | None = None) -> int:
    """``python3 -m host.bench.noise OUT.cap [--hours H] [--seed S]``: write a static capture with
    the known noise of :meth:`NoiseTruth.mpu6000` (for trying ``python3 -m host noise``)."""
    import argparse

    p = argparse.ArgumentParser(prog="python3 -m host.bench.noise", description=main.__doc__)
    p.add_argument("out", help="capture file to write")
    p.add_argument("--hours", type=float, default=4.0, help="length, h (default 4)")
    p.add_argument("--seed", type=int, default=3, help="random seed (default 3)")
    a = p.parse_args(argv)
    t, x, temp = static_noise(NoiseTruth.mpu6000(), a.hours * 3600.0, np.random.default_rng(a.seed))
    with open(a.out, "wb") as f:
        f.write(capture_bytes(t, x, temp))
    print(f"written: {a.out} ({t.size} samples)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
