"""The self-test's judge (host/wire/selftest.py): the factory trim of the register map (RM
rev 4.2 p.9-11), the ±14 % limit (PS rev 3.4 p.12-13), a moved unit, the C4/C5 sensitivity."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from host.wire.selftest import (
    AXES,
    MOVED_FRACTION,
    accel_factory_trim,
    gyro_factory_trim,
    judge,
    trim_codes,
)

# SELF_TEST_X/Y/Z/A bytes built by hand from the register map's bit layout:
# XA = 22 = 0b101_10, YA = 5 = 0b001_01, ZA = 31 = 0b111_11; XG = 7, YG = 1, ZG = 30
REGS = (0b101_00111, 0b001_00001, 0b111_11110, 0b00_10_01_11)
ACCEL_CODES, GYRO_CODES = (22, 5, 31), (7, 1, 30)


def test_trim_codes_are_read_from_the_bits_the_register_map_gives() -> None:
    assert trim_codes(*REGS) == (ACCEL_CODES, GYRO_CODES)


def test_factory_trim_at_the_formulas_ends_and_steps() -> None:
    # gyro: 25 °/s at 131 LSB/(°/s) for code 1, 4.6 % more per code, Y negative (RM p.10)
    assert gyro_factory_trim(1, 0) == pytest.approx(3275.0)
    assert gyro_factory_trim(1, 1) == pytest.approx(-3275.0)
    assert gyro_factory_trim(11, 2) / gyro_factory_trim(10, 2) == pytest.approx(1.046)
    # accel: 0.34 g at code 1 up to 0.92 g at code 31, 4096 LSB/g at ±8 g (RM p.11)
    assert accel_factory_trim(1) == pytest.approx(0.34 * 4096)
    assert accel_factory_trim(31) == pytest.approx(0.92 * 4096)
    assert accel_factory_trim(16) == pytest.approx(math.sqrt(0.34 * 0.92) * 4096)
    assert accel_factory_trim(0) == gyro_factory_trim(0, 0) == 0.0
    with pytest.raises(ValueError, match="5 bits"):
        accel_factory_trim(32)


def fields(
    deviation: dict[str, float] | None = None,
    gain: float = 1.0,
    moved: dict[str, float] | None = None,
    base: float = 100.0,
) -> dict[str, int]:
    """A SELF_TEST_RESULT whose response is each axis' trim × (1 + deviation); accelerometer
    counts × ``gain`` (0.5: a C4/C5 part); ``moved`` adds that many counts to the last window."""
    deviation, moved = deviation or {}, moved or {}
    f = dict(status=0, self_test_x=REGS[0], self_test_y=REGS[1], self_test_z=REGS[2],
             self_test_a=REGS[3], samples=32)  # fmt: skip
    for k, name in enumerate(AXES):
        i = k % 3
        if k < 3:
            trim = gain * accel_factory_trim(ACCEL_CODES[i])
        else:
            trim = gyro_factory_trim(GYRO_CODES[i], i)
        off = base * (k + 1) * (-1) ** k
        f[f"{name}_off"] = round(off)
        f[f"{name}_on"] = round(off + trim * (1 + deviation.get(name, 0.0)))
        f[f"{name}_end"] = round(off + moved.get(name, 0.0))
    return f


def test_a_part_at_its_trim_passes_and_says_so_in_its_record_header() -> None:
    st_ = judge(fields({"ax": 0.05, "gy": -0.1}))
    assert st_.outcome == "pass" and st_.reason == ""
    assert [round(100 * a.change) for a in st_.axes] == [5, 0, 0, 0, -10, 0]
    meta = st_.meta()
    assert meta["self_test"] == "pass"
    pct = [float(x) for x in meta["self_test_change_pct"].split()]
    assert pct == pytest.approx([5.0, 0.0, 0.0, 0.0, -10.0, 0.0], abs=0.06)  # counts are whole
    assert all(len(line) <= 80 for line in st_.lines())


@given(st.sampled_from(AXES), st.floats(-0.6, 0.6).filter(lambda d: abs(abs(d) - 0.14) > 0.005))
def test_an_axis_beyond_14_percent_fails_the_part_and_is_named(axis: str, dev: float) -> None:
    st_ = judge(fields({axis: dev}))
    if abs(dev) > 0.14:
        assert st_.outcome == "fail" and axis in st_.reason
        assert [a.name for a in st_.axes if a.passed is False] == [axis]
    else:
        assert st_.outcome == "pass"


def test_a_response_of_the_wrong_sign_fails() -> None:
    st_ = judge(fields({"gy": -2.0}))  # Y's trim is negative: a positive response is -200 %
    assert st_.outcome == "fail" and st_.axes[4].change == pytest.approx(-2.0, abs=1e-3)


def test_a_unit_that_moved_gets_no_verdict_and_no_header_line() -> None:
    trim = accel_factory_trim(ACCEL_CODES[2])
    st_ = judge(fields({"az": 0.5}, moved={"az": 2 * MOVED_FRACTION * trim}))
    assert st_.outcome == "" and "moved" in st_.reason and "az" in st_.reason
    assert "self_test" not in st_.meta() and "moved" in st_.meta()["self_test_note"]
    # a drift within the bound is no motion, and half of it cancels in the response
    st_ = judge(fields(moved={"az": 0.5 * MOVED_FRACTION * trim}))
    assert st_.outcome == "pass" and st_.axes[2].change == pytest.approx(-0.0125, abs=2e-3)


def test_a_half_sensitivity_part_is_judged_in_g() -> None:
    half = fields(gain=0.5)
    assert judge(half, product_id=0x55).outcome == "pass"  # C5 counts half the LSB/g
    st_ = judge(half, product_id=0x58)  # read as a D8 its response would be half
    assert st_.outcome == "fail" and st_.axes[0].change == pytest.approx(-0.5, abs=1e-3)


def test_an_incomplete_self_test_or_an_untrimmed_axis_gives_no_verdict() -> None:
    st_ = judge({**fields(), "status": 1})
    assert st_.outcome == "" and "NO_DATA" in st_.reason and st_.axes == ()
    untrimmed = {**fields(), "self_test_z": REGS[2] & 0xE0}  # ZG_TEST = 0
    st_ = judge(untrimmed)
    assert st_.outcome == "" and "gz" in st_.reason and math.isnan(st_.axes[5].change)
