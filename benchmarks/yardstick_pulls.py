"""The yardstick's pulls (issue 24): the truth behind each fitted value, and the groups their
pulls (fitted − truth)/σ are counted in.

Used by :mod:`benchmarks.yardstick`: :func:`truth_of` finds the simulator's truth for a
workbench parameter name (method.md's constants, the catalogue's ``term.sensor.axis`` names,
the plate's tilt in the frame the workbench reads it in), :func:`pulls_of` pairs them,
:func:`pull_group` and :func:`pull_stats` make the table's rows.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

Truth = dict[str, Any]


def effect_of(t: Truth) -> dict[str, Any]:
    """The simulated session's one effect (its name and parameters) from its truth."""
    return dict(t["effect"])


def truth_of(name: str, t: Truth) -> float | None:
    """The truth behind a workbench parameter name (method.md's constants, the catalogue's
    ``term.sensor.axis`` names), or None if the simulator did not set it."""
    c = t["constants"]
    if name in c:
        return float(c[name])
    e = effect_of(t)
    parts = name.split(".")
    if parts[0] == "plate_tilt" and "up_east_rad" in e:
        # a turn's heading correction: its truth is the circle's error, not written down
        return None if parts[-1] == "heading" else plate_truth(parts, t)
    if parts[0] == "lever_arm" and "r_m" in e:
        return float(e["r_m"]["xyz".index(parts[1])])
    if parts[0] == "face_error" and e["name"] == "face_lean" and len(parts) == 4:
        # the pair's mean lean as the accelerometer reads it: [C_A·θ̄]_i / C_A,ii (its
        # misalignment puts the lean toward the third axis on channel i too; the fit states
        # the lean in the accelerometer's frame, tests/independent/test_independent_geometry)
        i, j = "xyz".index(parts[2]), parts[3][-1]
        lean = e["lean_rad"]
        mean = 0.5 * (np.asarray(lean["+" + j]) + np.asarray(lean["-" + j]))
        ca = accel_matrix(c)
        return float((ca @ mean)[i] / ca[i, i])
    keys = {"time_drift": "per_h", "temperature_bias": "per_C", "scale_asymmetry": "asym",
            "scale_nonlinearity": "k2"}  # fmt: skip
    if len(parts) == 3 and parts[0] in keys and keys[parts[0]] in e:
        if parts[1] == e.get("sensor") and parts[2] == e.get("axis"):
            return float(e[keys[parts[0]]])
        return 0.0  # the same term on another channel: nothing there
    return None


def accel_matrix(c: dict[str, Any]) -> np.ndarray:
    """The accelerometer's I + M from method.md's constants (the signs of §2: x row (1+Sxx,
    Sxz, −Sxy), y row (−Syz, 1+Syy, Syx), z row (Szy, −Szx, 1+Szz))."""
    return np.array([
        [1 + c["Axx"], c["Axz"], -c["Axy"]],
        [-c["Ayz"], 1 + c["Ayy"], c["Ayx"]],
        [c["Azy"], -c["Azx"], 1 + c["Azz"]],
    ])  # fmt: skip


def plate_truth(parts: Sequence[str], t: Truth) -> float:
    """The truth of a plate_tilt parameter in the frame the workbench reads it in: the fence
    when headings are recorded, else the first turn's reference axis (the host's frame when no
    record carries its heading); a record's own ``seen_ref``/``seen_side`` (its heading not
    recorded): the tilt turned by −(its heading)."""
    e = effect_of(t)
    up = np.array([float(e["up_east_rad"]), float(e["up_north_rad"])])
    heads = t["headings_deg"]
    if len(parts) == 3:  # plate_tilt.<record>.seen_ref|seen_side
        psi = float(heads[parts[1]])
        key = parts[2]
    else:
        turns = sorted(n for n in heads if n.endswith(("_cw", "_ccw")))
        psi = 0.0 if t["spec"].get("record_heading") else float(heads[turns[0]])
        key = parts[1]
    a = math.radians(psi)
    seen = np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]]) @ up
    return float(seen[0 if key in ("east", "seen_ref") else 1])


def pulls_of(params: Iterable[dict[str, Any]], t: Truth, prefix: str = "") -> list[list[Any]]:
    """[name, fitted, σ, truth] of every parameter in ``params`` (the workbench's JSON) whose
    truth the simulator set and whose σ is finite; ``prefix`` marks calibration constants."""
    out = []
    for p in params:
        truth = truth_of(str(p["name"]), t)
        se = p.get("stderr")
        if truth is None or not se or not math.isfinite(float(se)):
            continue
        out.append([prefix + str(p["name"]), float(p["value"]), float(se), truth])
    return out


#: the calibration constants in groups of like values (method.md §7's groups)
CONST_GROUPS = (
    ("A0", "accel bias"), ("G0", "gyro bias"), ("GA", "gyro g-sensitivity"),  # before G..
)  # fmt: skip


def pull_group(name: str) -> str:
    """The row a pull is counted in: calibration constants by §7 group, a term's coefficients
    over its channels (``time_drift.gyro.*``), the shared terms' parameters one by one."""
    if name.startswith("cal "):
        c = name[4:]
        for prefix, label in CONST_GROUPS:
            if c.startswith(prefix):
                return f"cal {label}"
        kind = "scale" if c[1] == c[2] else "misalignment"
        sensor = "accel" if c[0] == "A" else "gyro"
        return f"cal {sensor} {kind}"
    parts = name.split(".")
    if len(parts) == 3 and parts[0] == "plate_tilt":  # a record's own view of the tilt
        return f"plate_tilt.*.{parts[2]}"
    if len(parts) >= 3 and parts[0] not in ("plate_tilt", "lever_arm"):
        return ".".join(parts[:2]) + ".*"
    return name


def pull_stats(members: dict[str, list[float]]) -> dict[str, Any]:
    """Pooled mean/sd/share beyond 3 of a group's pulls, the range of its members' sd (members
    with at least 3 values) and the number of members ``k``."""
    allv = np.concatenate([np.asarray(v, dtype=float) for v in members.values()])
    sds = [float(np.std(v, ddof=1)) for v in members.values() if len(v) > 2]
    return {
        "n": int(max(len(v) for v in members.values())), "members": len(members),
        "mean": float(np.mean(allv)),
        "sd": float(np.std(allv, ddof=1)) if allv.size > 1 else math.nan,
        "sd_lo": min(sds) if sds else math.nan, "sd_hi": max(sds) if sds else math.nan,
        "beyond3": float(np.mean(np.abs(allv) > 3)),
    }  # fmt: skip
