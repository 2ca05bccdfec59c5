"""The port a flasher opens: a device as it is, a URL through its transport's adapter."""

from __future__ import annotations

import pytest

from host.errors import UserError
from host.transports.flashing import FlashPort, flash_port


@pytest.mark.parametrize("port", ["/dev/ttyACM0", "COM3", "sim://", "nosuch://x", "a-b://"])
def test_a_device_or_a_scheme_without_a_flash_adapter_is_passed_on_as_it_is(port: str) -> None:
    with flash_port(port) as target:
        assert target == FlashPort(port)
    assert target.summary is None


@pytest.mark.parametrize(
    ("url", "message"),
    [
        ("emu://", r"needs a flash file to keep what is flashed: --port 'emu://\?flash=PATH'"),
        ("emu://?flash=", r"needs a flash file"),
        ("emu://?colour=red", r"^emu:// option colour='red': unknown option$"),
    ],
)
def test_the_emulator_adapter_refuses_before_it_starts_anything(url: str, message: str) -> None:
    with pytest.raises(UserError, match=message), flash_port(url):
        raise AssertionError("served a port it should have refused")
