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

#: PRODUCT_ID (register 0x0C, undocumented in RM rev 4.2; read by ArduPilot's and PX4's
#: drivers) -> revision name. High nibble 0x5: MPU-6000, 0x1: engineering sample ("ES").
PRODUCT_REVISIONS = {
    0x14: "ES C4", 0x15: "ES C5", 0x16: "ES D6", 0x17: "ES D7", 0x18: "ES D8",
    0x54: "C4", 0x55: "C5", 0x56: "D6", 0x57: "D7", 0x58: "D8", 0x59: "D9", 0x5A: "D10",
}  # fmt: skip
#: revisions C4/C5 have half the accelerometer sensitivity of the datasheet's table at every
#: AFS_SEL (ArduPilot's MPU-6000 driver: "rev C has 1/2 the sensitivity of rev D")
HALF_ACCEL_SENSITIVITY = frozenset({0x14, 0x15, 0x54, 0x55})
#: the revision the emulator and the simulator are by default
DEFAULT_PRODUCT_ID = 0x58


def revision_name(product_id: int | None) -> str:
    """``0x55`` -> ``"C5"``; an unknown id -> ``"unknown 0xNN"``; None -> ``"not reported"``."""
    if product_id is None:
        return "not reported"
    return PRODUCT_REVISIONS.get(product_id, f"unknown {product_id:#04x}")


def revision_warning(product_id: int | None) -> str | None:
    """What to tell the user when the part's PRODUCT_ID is no known MPU-6000 revision (None
    when it is known, or not reported): its accelerometer is scaled as a revision D part's."""
    if product_id is None or product_id in PRODUCT_REVISIONS:
        return None
    known = ", ".join(f"{n} {p:#04x}" for p, n in PRODUCT_REVISIONS.items() if n[0] != "E")
    return (
        f"the sensor's PRODUCT_ID {product_id:#04x} is no known MPU-6000 revision ({known}): "
        "its accelerometer is scaled as a revision D part's (the datasheet's LSB/g); a C4/C5 "
        "counts half as much, so if 1 g does not read about 9.8 m/s², check the part"
    )


def product_id_of(text: str) -> int:
    """A revision as a user writes it (``C4``, ``es d8``, ``D10``) or a PRODUCT_ID number
    (``0x55``, ``85``) -> the PRODUCT_ID; ValueError naming the known revisions otherwise."""
    t = " ".join(text.upper().replace("_", " ").split())
    for pid, name in PRODUCT_REVISIONS.items():
        if t in (name, name.replace(" ", "")):
            return pid
    try:
        pid = int(text, 0)
    except ValueError:
        pid = -1
    if 0 <= pid <= 0xFF:
        return pid
    known = ", ".join(n for n in PRODUCT_REVISIONS.values() if not n.startswith("ES"))
    raise ValueError(f"unknown MPU-6000 revision {text!r}; known: {known} (or ES C4 ...)")


def identity_meta(who_am_i: int | None, product_id: int | None) -> dict[str, str]:
    """Record header lines naming the sensor (``host.session.records.SENSOR_KEYS``): WHO_AM_I,
    PRODUCT_ID and its revision name; a value the board did not report is left out."""
    out: dict[str, str] = {}
    if who_am_i is not None:
        out["who_am_i"] = f"{who_am_i:#04x}"
    if product_id is not None:
        out["product_id"] = f"{product_id:#04x}"
        out["sensor_revision"] = revision_name(product_id)
    return out


def accel_lsb_per_g(afs_sel: int = 0, product_id: int | None = None) -> float:
    """Accelerometer sensitivity, LSB/g, of AFS_SEL on the part with this PRODUCT_ID (datasheet
    p. 13; halved on revisions C4/C5; None = the datasheet's value)."""
    lsb = ACCEL_LSB_PER_G[afs_sel]
    return lsb / 2.0 if product_id in HALF_ACCEL_SENSITIVITY else lsb


def accel_range_g(afs_sel: int = 0, product_id: int | None = None) -> int:
    """Full-scale range, ±g, of AFS_SEL on this part (doubled on revisions C4/C5: the counts
    span twice the g); 0 for an impossible AFS_SEL."""
    if afs_sel not in ACCEL_RANGE_G:
        return 0
    return ACCEL_RANGE_G[afs_sel] * (2 if product_id in HALF_ACCEL_SENSITIVITY else 1)


def accel_mps2(
    counts: np.ndarray | int, afs_sel: int = 0, product_id: int | None = None
) -> np.ndarray:
    """Accelerometer counts -> specific force in m/s² (``product_id``: see accel_lsb_per_g)."""
    return np.asarray(counts, dtype=np.float64) * (G0 / accel_lsb_per_g(afs_sel, product_id))


def gyro_dps(counts: np.ndarray | int, fs_sel: int = 0) -> np.ndarray:
    """Gyro counts -> angular rate in °/s."""
    return np.asarray(counts, dtype=np.float64) / GYRO_LSB_PER_DPS[fs_sel]


def temp_c(counts: np.ndarray | int) -> np.ndarray:
    """TEMP_OUT counts -> die temperature in °C (datasheet register map p. 31: /340 + 36.53)."""
    return np.asarray(counts, dtype=np.float64) / 340.0 + 36.53


def accel_counts(mps2: np.ndarray, afs_sel: int = 0, product_id: int | None = None) -> np.ndarray:
    """Specific force in m/s² -> int16 counts, rounded and saturated at ±32767."""
    c = np.rint(np.asarray(mps2, dtype=np.float64) * (accel_lsb_per_g(afs_sel, product_id) / G0))
    return np.clip(c, -32768, 32767).astype(np.int16)


def gyro_counts(dps: np.ndarray, fs_sel: int = 0) -> np.ndarray:
    """Angular rate in °/s -> int16 counts, rounded and saturated at ±32767."""
    c = np.rint(np.asarray(dps, dtype=np.float64) * GYRO_LSB_PER_DPS[fs_sel])
    return np.clip(c, -32768, 32767).astype(np.int16)


def temp_counts(celsius: np.ndarray) -> np.ndarray:
    """Die temperature in °C -> TEMP_OUT int16 counts."""
    c = np.rint((np.asarray(celsius, dtype=np.float64) - 36.53) * 340.0)
    return np.clip(c, -32768, 32767).astype(np.int16)
