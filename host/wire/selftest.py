"""The MPU-6000 self-test judged from the firmware's raw result (the SELF_TEST_RESULT frame).

The firmware reads the factory trim registers and averages three windows at the self-test ranges
(accelerometer ±8 g, gyroscope ±250 °/s): self-test off, on, off again. Everything else is here,
as pure functions:

- the factory trim FT of each axis from its 5-bit code (register map RM-MPU-6000A-00 rev 4.2,
  p.9-11): gyroscope ``25 · 131 · 1.046^(code − 1)`` LSB at ±250 °/s (negative for Y), the
  accelerometer ``4096 · 0.34 · (0.92 / 0.34)^((code − 1) / 30)`` LSB at ±8 g, i.e. 0.34 g to
  0.92 g; code 0: no trim;
- the self-test response STR = on − the mean of the two off windows (a slow drift cancels);
- the change from factory trim ``(STR − FT) / FT``, which must lie within ±14 % (product
  specification PS-MPU-6000A-00 rev 3.4, p.12-13) for the part to pass;
- whether the unit moved meanwhile: the two off windows differ by more than
  :data:`MOVED_FRACTION` of the axis' trim. Then no verdict is given (repeat with the unit
  still), because a tilt changes what the accelerometers sense as much as the self-test does.

The accelerometer is compared in g with the part's own sensitivity: C4/C5 parts count half the
LSB/g (:func:`host.wire.sensor.accel_lsb_per_g`), so their response in counts is half as large.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from host.wire import protocol_gen as gen
from host.wire import sensor

#: the change from factory trim a passing axis stays within (PS p.12-13: −14 % … +14 %)
LIMIT = 0.14
#: the two self-test-off windows may differ by this fraction of the axis' factory trim (more:
#: the unit moved or the bias jumped; the response would be off by about half of it)
MOVED_FRACTION = 0.05
#: AFS_SEL of the accelerometer self-test (±8 g, RM p.11) and FS_SEL of the gyroscope's (±250 °/s)
ACCEL_FS_SEL = 2
GYRO_FS_SEL = 0
#: the outcome of a self-test the operator chose not to run (``calibrate --no-self-test``)
NOT_RUN = "not run"
#: the self-test's outcomes as records and the archive write them ('' = no verdict, or records
#: from before the self-test)
OUTCOMES = ("pass", "fail", NOT_RUN, "")
AXES = ("ax", "ay", "az", "gx", "gy", "gz")
_DONE = gen.ENUMS["self_test_status"]["DONE"]
_STATUS_NAMES = {v: k for k, v in gen.ENUMS["self_test_status"].items()}


def gyro_factory_trim(code: int, axis: int) -> float:
    """FT of gyroscope ``axis`` (0 x, 1 y, 2 z) from its XG/YG/ZG_TEST code (0…31), LSB at
    ±250 °/s (RM p.10); 0.0 for code 0 (no trim). The Y axis' is negative."""
    if not 0 <= code <= 31:
        raise ValueError(f"a self-test code is 5 bits, not {code}")
    if code == 0:
        return 0.0
    sign = -1.0 if axis == 1 else 1.0
    return sign * 25.0 * 131.0 * 1.046 ** (code - 1)


def accel_factory_trim(code: int) -> float:
    """FT of an accelerometer axis from its XA/YA/ZA_TEST code (0…31), LSB at ±8 g
    (4096 LSB/g, RM p.11); 0.0 for code 0 (no trim)."""
    if not 0 <= code <= 31:
        raise ValueError(f"a self-test code is 5 bits, not {code}")
    if code == 0:
        return 0.0
    return 4096.0 * 0.34 * (0.92 / 0.34) ** ((code - 1) / 30.0)


def trim_codes(st_x: int, st_y: int, st_z: int, st_a: int) -> tuple[tuple[int, ...], ...]:
    """The SELF_TEST_X/Y/Z/A register bytes -> ((XA, YA, ZA codes), (XG, YG, ZG codes)).
    An accelerometer code is XA_TEST[4:2] (bits 7…5 of SELF_TEST_X) above XA_TEST[1:0]
    (bits 5…4 of SELF_TEST_A; Y bits 3…2, Z bits 1…0); a gyroscope code is bits 4…0."""
    regs = (st_x, st_y, st_z)
    accel = tuple(((r >> 5) & 0x7) << 2 | (st_a >> (4 - 2 * i)) & 0x3 for i, r in enumerate(regs))
    gyro = tuple(r & 0x1F for r in regs)
    return accel, gyro


@dataclass(frozen=True)
class AxisCheck:
    """One axis of the self-test. ``factory_trim`` and ``response`` in counts at the self-test
    range (accelerometer: counts of a part with 4096 LSB/g), ``moved`` = |off again − off| in
    the same counts; ``change`` = (response − trim) / trim (NaN without a trim);
    ``passed``: None when the axis cannot be judged (no trim, or the unit moved)."""

    name: str
    code: int
    factory_trim: float
    response: float
    moved: float
    change: float
    passed: bool | None


@dataclass(frozen=True)
class SelfTest:
    """The judged self-test: ``outcome`` 'pass', 'fail', :data:`NOT_RUN` or '' (no verdict),
    ``reason`` why when it is not 'pass', the six :class:`AxisCheck` (ax ay az gx gy gz)."""

    outcome: str
    reason: str
    axes: tuple[AxisCheck, ...]
    samples: int

    def meta(self) -> dict[str, str]:
        """Record header lines: ``self_test`` (pass or fail; absent without a verdict), when the
        windows were valid ``self_test_change_pct`` (the six changes from factory trim, %,
        ax ay az gx gy gz), and ``self_test_note`` (why it is not a pass)."""
        out = {"self_test": self.outcome} if self.outcome else {}
        if self.axes:
            out["self_test_change_pct"] = " ".join(
                "nan" if math.isnan(a.change) else f"{100 * a.change:+.1f}" for a in self.axes
            )
        if self.reason:
            out["self_test_note"] = " ".join(self.reason.split())
        return out

    def lines(self) -> list[str]:
        """What to show: the verdict, then one line per axis (≤ 80 columns)."""
        head = {"pass": "PASS", "fail": "FAIL", NOT_RUN: "NOT RUN", "": "NO VERDICT"}[self.outcome]
        out = [f"MPU-6000 self-test: {head}" + (f" — {self.reason}" if self.reason else "")]
        for a in self.axes:
            unit = "g" if a.name.startswith("a") else "°/s"
            scale = 4096.0 if unit == "g" else 131.0
            change = "   n/a" if math.isnan(a.change) else f"{100 * a.change:+6.1f} %"
            mark = {True: "ok", False: "OUT OF ±14 %", None: "-"}[a.passed]
            out.append(
                f"  {a.name}: response {a.response / scale:8.3f} {unit:<3} trim "
                f"{a.factory_trim / scale:8.3f} {unit:<3} change {change}  {mark}"
            )
        return out


def judge(fields: Mapping[str, int], product_id: int | None = None) -> SelfTest:
    """A SELF_TEST_RESULT frame's fields -> :class:`SelfTest`; ``product_id`` (HELLO's) gives
    the accelerometer's sensitivity (C4/C5 count half)."""
    status = int(fields["status"])
    if status != _DONE:
        name = _STATUS_NAMES.get(status, f"status {status}")
        return SelfTest("", f"the self-test did not complete ({name})", (), 0)
    accel_codes, gyro_codes = trim_codes(
        fields["self_test_x"], fields["self_test_y"], fields["self_test_z"], fields["self_test_a"]
    )
    # counts of this part -> counts of a 4096 LSB/g part (the trim's unit)
    accel_gain = 4096.0 / sensor.accel_lsb_per_g(ACCEL_FS_SEL, product_id)
    axes = []
    for k, name in enumerate(AXES):
        i = k % 3
        if k < 3:
            code, trim, gain = accel_codes[i], accel_factory_trim(accel_codes[i]), accel_gain
        else:
            code, trim, gain = gyro_codes[i], gyro_factory_trim(gyro_codes[i], i), 1.0
        off, on, end = (gain * fields[f"{name}_{w}"] for w in ("off", "on", "end"))
        response = on - 0.5 * (off + end)
        moved = abs(end - off)
        change = (response - trim) / trim if trim else math.nan
        passed: bool | None = None
        if trim and moved <= MOVED_FRACTION * abs(trim):
            passed = abs(change) <= LIMIT
        axes.append(AxisCheck(name, code, trim, response, moved, change, passed))
    moved_axes = [a.name for a in axes if a.factory_trim and a.passed is None]
    failed = [a.name for a in axes if a.passed is False]
    untrimmed = [a.name for a in axes if not a.factory_trim]
    if moved_axes:
        outcome = ""
        reason = f"the unit moved during the self-test ({', '.join(moved_axes)}): repeat it still"
    elif failed:
        outcome, reason = "fail", f"{', '.join(failed)} outside ±14 % of the factory trim"
    elif untrimmed:
        outcome, reason = "", f"no factory trim for {', '.join(untrimmed)} (code 0)"
    else:
        outcome, reason = "pass", ""
    return SelfTest(outcome, reason, tuple(axes), int(fields["samples"]))
