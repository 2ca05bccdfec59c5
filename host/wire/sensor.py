"""MPU-6000 count <-> physical unit conversions (datasheet PS-MPU-6000A-00 rev 3.4, pp. 12-13).

Firmware sends raw counts; the host does the physics here, in one place.
"""

from __future__ import annotations

import numpy as np

#: standard gravity used to turn the datasheet's LSB/g into m/s² (the local g is separate)
G0 = 9.80665

#: ACCEL_CONFIG AFS_SEL -> LSB per g (datasheet p. 13)
ACCEL_LSB_PER_G = {0: 16384.0, 1: 8192.0, 2: 4096.0, 3: 2048.0}
#: GYRO_CONFIG FS_SEL -> LSB per °/s (datasheet p. 12)
GYRO_LSB_PER_DPS = {0: 131.0, 1: 65.5, 2: 32.8, 3: 16.4}
#: full-scale ranges
ACCEL_RANGE_G = {0: 2, 1: 4, 2: 8, 3: 16}
GYRO_RANGE_DPS = {0: 250, 1: 500, 2: 1000, 3: 2000}

WHO_AM_I_MPU6000 = 0x68


def accel_mps2(counts: np.ndarray | int, afs_sel: int = 0) -> np.ndarray:
    """Accelerometer counts -> specific force in m/s²."""
    return np.asarray(counts, dtype=np.float64) * (G0 / ACCEL_LSB_PER_G[afs_sel])


def gyro_dps(counts: np.ndarray | int, fs_sel: int = 0) -> np.ndarray:
    """Gyro counts -> angular rate in °/s."""
    return np.asarray(counts, dtype=np.float64) / GYRO_LSB_PER_DPS[fs_sel]


def temp_c(counts: np.ndarray | int) -> np.ndarray:
    """TEMP_OUT counts -> die temperature in °C (datasheet register map p. 31: /340 + 36.53)."""
    return np.asarray(counts, dtype=np.float64) / 340.0 + 36.53


def accel_counts(mps2: np.ndarray, afs_sel: int = 0) -> np.ndarray:
    """Specific force in m/s² -> int16 counts, rounded and saturated at ±32767."""
    c = np.rint(np.asarray(mps2, dtype=np.float64) * (ACCEL_LSB_PER_G[afs_sel] / G0))
    return np.clip(c, -32768, 32767).astype(np.int16)


def gyro_counts(dps: np.ndarray, fs_sel: int = 0) -> np.ndarray:
    """Angular rate in °/s -> int16 counts, rounded and saturated at ±32767."""
    c = np.rint(np.asarray(dps, dtype=np.float64) * GYRO_LSB_PER_DPS[fs_sel])
    return np.clip(c, -32768, 32767).astype(np.int16)


def temp_counts(celsius: np.ndarray) -> np.ndarray:
    """Die temperature in °C -> TEMP_OUT int16 counts."""
    c = np.rint((np.asarray(celsius, dtype=np.float64) - 36.53) * 340.0)
    return np.clip(c, -32768, 32767).astype(np.int16)
