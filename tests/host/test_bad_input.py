"""Input from outside is validated where it enters, with the user's words (issue 17):
URL options of sim:// and emu:// (a sim at speed=inf or a clock off by 1e9 ppm spun at 100 %
CPU; emu://?elf=<not an ELF> said the board disconnected)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from host.errors import UserError
from host.link import open_port
from host.transports import protocol_emu


@pytest.mark.timeout(20)
@pytest.mark.parametrize(
    "option, words",
    [
        ("speed=inf", "speed='inf' is outside 0.1 … 1000"),
        ("speed=nan", "speed='nan' is outside"),
        ("speed=1e-9", "speed='1e-9' is outside"),
        ("clock_ppm=1e9", "clock_ppm='1e9' is outside -10000 … 10000"),
        ("clock_ppm=x", "clock_ppm='x' is not a number"),
        ("sample_clock=0.5", "sample_clock='0.5' is outside"),
        ("latitude=95", "latitude='95' is outside -90 … 90"),
        ("fault=pull_cable@inf", "is outside 0 … 1e+06"),
    ],
)
def test_sim_url_options_out_of_range_are_refused(option: str, words: str) -> None:
    t0 = time.monotonic()
    with pytest.raises(UserError) as err:
        open_port(f"sim://?{option}")
    assert words in str(err.value)
    assert "USB cable" not in str(err.value)  # not a cable problem: the URL's option
    assert time.monotonic() - t0 < 5


def test_sim_url_in_range_still_opens() -> None:
    p = open_port("sim://?speed=1000&clock_ppm=-9999&sample_clock=0.01&latitude=-90")
    try:
        assert p.read(64)
    finally:
        p.close()


@pytest.mark.parametrize(
    "option, words",
    [
        ("speed=inf", "speed='inf' is outside 0.1 … 1000"),
        ("clock_ppm=1e9", "clock_ppm='1e9' is outside -50000 … 50000"),
        ("fault_at=nan", "fault_at='nan' is outside"),
        ("seconds=-1", "seconds='-1' is outside"),
    ],
)
def test_emu_url_options_out_of_range_are_refused(option: str, words: str) -> None:
    with pytest.raises(ValueError, match=words):
        protocol_emu.parse_url(f"emu://?{option}")
        protocol_emu.parse_sim_options(f"emu://?{option}")


def test_emu_elf_that_is_not_an_elf_says_so(tmp_path: Path) -> None:
    bad = tmp_path / "fw.elf"
    bad.write_text("hello, not firmware\n")
    with pytest.raises(UserError, match=r"elf=.*fw\.elf.*not an ELF or Intel HEX file"):
        open_port(f"emu://?elf={bad}")
    with pytest.raises(UserError, match=r"cannot read the firmware file \(No such file"):
        open_port(f"emu://?elf={tmp_path / 'missing.elf'}")
    good = tmp_path / "fw.hex"
    good.write_text(":00000001FF\n")
    assert protocol_emu.parse_url(f"emu://?elf={good}")["elf"] == str(good)
