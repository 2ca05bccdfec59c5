"""Kalibr's IMU configuration (``imu.yaml``) from a noise file (``noise FILE --save``): the
four continuous-time noise figures Kalibr wants, from the Allan analysis of a long static
recording (``python3 -m host export --to kalibr --noise NOISE.json``), not from a calibration.
"""

from __future__ import annotations

import math

from host.errors import InputError

DEG = math.pi / 180.0

#: Kalibr key -> (our channels, our figure, factor from our unit to Kalibr's)
KALIBR_KEYS = {
    "accelerometer_noise_density": (("ax", "ay", "az"), "white_noise_density", 1.0),
    "accelerometer_random_walk": (("ax", "ay", "az"), "rate_random_walk", 1.0),
    "gyroscope_noise_density": (("gx", "gy", "gz"), "white_noise_density", DEG),
    "gyroscope_random_walk": (("gx", "gy", "gz"), "rate_random_walk", DEG),
}


def kalibr_values(noise: dict[str, object]) -> tuple[dict[str, float], list[str]]:
    """Kalibr's four continuous-time noise figures from a noise document (``noise --save``):
    accelerometer m/s²/√Hz and m/s³/√Hz, gyroscope rad/s/√Hz and rad/s²/√Hz — the worst axis
    of each sensor (Kalibr has one value per sensor). A figure the recording did not resolve
    is exported at its upper confidence bound; the second item names each such figure."""
    chans = noise.get("channels")
    if not isinstance(chans, dict):
        raise InputError("noise file: no 'channels' (write one with: noise FILE --save)")
    out: dict[str, float] = {}
    bounds: list[str] = []
    for key, (names, fig, factor) in KALIBR_KEYS.items():
        vals = []
        for name in names:
            try:
                f = chans[name][fig]
                v = f["value"]
                if v is None:
                    v = f["ci"][1]
                    bounds.append(f"{key}: {name} {fig} not resolved, its upper bound is used")
                vals.append(float(v) * factor)
            except (KeyError, TypeError, IndexError, ValueError):
                raise InputError(f"noise file: channel {name} has no {fig}") from None
        out[key] = max(vals)
    return out, bounds


def export_kalibr(noise: dict[str, object], topic: str = "/imu0") -> str:
    """Kalibr's IMU configuration (imu.yaml) from a noise document: the noise densities are
    the white-noise Allan coefficients N, the random walks the rate-random-walk coefficients
    K, both continuous-time as Kalibr wants them, with nothing inflated (Kalibr's advice to
    inflate them for its discrete-time model is the user's decision, not made here)."""
    vals, bounds = kalibr_values(noise)
    rate = float(noise.get("rate_hz", 0.0) or 0.0)  # type: ignore[arg-type]
    lines = [
        "# Kalibr IMU noise model from an imu-bench noise file (python3 -m host noise --save)",
        "# continuous-time densities; the worst axis of each sensor; no inflation applied",
        f"# recording: {float(noise.get('duration_s', 0.0) or 0.0):.0f} s at {rate:.2f} Hz",  # type: ignore[arg-type]
        "# NOT REPRESENTED by this format: bias instability, per-axis figures, and every",
        "# calibration constant (Kalibr estimates its own intrinsics)",
    ]
    lines += [f"# {b}" for b in bounds]
    lines.append(f"rostopic: {topic}")
    lines.append(f"update_rate: {rate:.6g}")
    lines += [f"{k}: {v:.9g}" for k, v in vals.items()]
    return "\n".join(lines) + "\n"
