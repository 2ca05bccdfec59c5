"""One options parser for the virtual bench (host/bench/options.py): sim:// and emu:// read the
simulator's options the same way; ``fault=`` keeps its meaning on each scheme."""

from __future__ import annotations

import urllib.parse

import pytest
import serial

from host.bench.options import OptionError, SimOptions, parse_sim_options
from host.board.link import register_transports
from host.transports import protocol_emu

register_transports()


def opts(query: str) -> dict[str, list[str]]:
    return urllib.parse.parse_qs(query, keep_blank_values=True)


def test_both_schemes_read_the_shared_options_alike() -> None:
    q = "seed=7&truth=ideal&effects=linear,noise&operator=manual&latitude=-33.5&tilt=1.5"
    q += "&earth_rate=0"
    want = SimOptions(7, 4.0, "ideal", ("linear", "noise"), "manual", -33.5, 1.5, False)
    assert parse_sim_options(opts(q + "&speed=4"), "realtime", True) == want
    assert protocol_emu.parse_sim_options("emu://?" + q + "&speed=4") == want
    # only the default speed differs: sim:// follows the wall clock, emu:// runs flat out
    assert parse_sim_options(opts(""), "realtime", True).speed == 1.0
    assert protocol_emu.parse_sim_options("emu://") == SimOptions(speed=None)


def test_seeds_in_decimal_or_with_a_base_prefix() -> None:
    assert parse_sim_options(opts("seed=007"), "max", True).seed == 7  # sim:// always took this
    assert parse_sim_options(opts("seed=0x10"), "max", False).seed == 16  # emu:// took this


def test_same_seed_same_sensor_on_both_schemes() -> None:
    port = serial.serial_for_url("sim://?seed=11&noise_seed=11&speed=max", timeout=0.1)
    try:
        sim_truth = port.truth
    finally:
        port.close()
    emu_truth = protocol_emu.truth_for_url("emu://?seed=11&noise_seed=11")
    assert sim_truth is not None and emu_truth is not None
    assert sim_truth.constants() == emu_truth.constants()


def test_fault_keeps_its_meaning_and_operator_fault_is_one_spelling_for_both() -> None:
    old = parse_sim_options(opts("fault=too_fast@2&fault=pull_cable@3"), "max", True)
    new = parse_sim_options(opts("operator_fault=too_fast@2&fault=pull_cable"), "max", True)
    assert old.operator_faults == new.operator_faults == (("too_fast", 2.0),)
    assert (old.cable_pull_s, new.cable_pull_s) == (3.0, 5.0)
    emu = protocol_emu.parse_sim_options("emu://?operator_fault=too_fast@2&fault=no-drdy")
    assert emu is not None and emu.operator_faults == (("too_fast", 2.0),)
    assert protocol_emu.parse_url("emu://?fault=no-drdy")["fault"] == "no-drdy"  # the sensor's
    with pytest.raises(ValueError, match="emu:// option operator_fault='pull_cable'"):
        protocol_emu.parse_sim_options("emu://?operator_fault=pull_cable")  # no cable to pull


def test_a_bad_option_is_named() -> None:
    bad = [("speed=0", "speed"), ("truth=perfect", "truth"), ("tilt=x", "tilt"),
           ("operator_fault=dance", "operator_fault"), ("seed=one", "seed"),
           ("noise_seed=0x", "noise_seed")]  # fmt: skip
    for query, key in bad:
        with pytest.raises(OptionError) as err:
            parse_sim_options(opts(query), "max", True)
        assert err.value.key == key
    with pytest.raises(serial.SerialException, match="sim:// URL: unknown fault 'dance'"):
        serial.serial_for_url("sim://?operator_fault=dance")


def test_the_chamber_ramp_is_the_same_on_both_schemes() -> None:
    from host.bench.options import parse_chamber

    want = tuple(parse_chamber("-10:50:60@30").items())
    o = parse_sim_options(opts("chamber=-10:50:60@30"), "realtime", True)
    e = protocol_emu.parse_sim_options("emu://?chamber=-10:50:60@30")
    assert o.chamber == want and e is not None and e.chamber == want
    env = o.draw().environment
    assert (env.chamber_from_c, env.chamber_to_c, env.chamber_minutes) == (-10.0, 50.0, 60.0)
