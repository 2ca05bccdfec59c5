"""platformio.ini is valid for PlatformIO and agrees with the Makefile build.

PlatformIO's package registry is unreachable here, so only the project configuration is checked
(offline: `pio project config --json-output`), not a PlatformIO build."""

from __future__ import annotations

import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys

import pytest
from fwbuild import FIRMWARE, ROOT


def pio_command() -> list[str]:
    if importlib.util.find_spec("platformio") is not None:
        return [sys.executable, "-m", "platformio"]
    exe = shutil.which("pio") or shutil.which("platformio")
    if exe is None:
        pytest.skip(
            "PlatformIO is not installed (pip install platformio); the ini is not validated"
        )
    return [exe]


@pytest.fixture(scope="module")
def apm_env(tmp_path_factory) -> dict:
    env = dict(os.environ, PLATFORMIO_CORE_DIR=str(tmp_path_factory.mktemp("pio-core")))
    r = subprocess.run(
        pio_command() + ["project", "config", "--json-output"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    assert r.returncode == 0, f"pio rejected platformio.ini:\n{r.stdout}{r.stderr}"
    sections = {name: dict(opts) for name, opts in json.loads(r.stdout)}
    assert "env:apm" in sections, sections.keys()
    assert sections["platformio"]["default_envs"] == ["apm"]
    assert os.path.realpath(sections["platformio"]["src_dir"]) == str(FIRMWARE / "src")
    return sections["env:apm"]


def test_ini_targets_the_apm(apm_env) -> None:
    assert apm_env["platform"] == "atmelavr"
    assert apm_env["board"] == "megaatmega2560"
    assert "framework" not in apm_env  # bare avr-libc
    assert apm_env["board_build.mcu"] == "atmega2560"
    assert apm_env["board_build.f_cpu"] == "16000000UL"
    assert apm_env["upload_protocol"] == "wiring"
    assert apm_env["upload_speed"] == 115200
    assert "-D" in apm_env["upload_flags"]


def test_ini_options_are_known_to_platformio(apm_env) -> None:
    if importlib.util.find_spec("platformio") is None:
        pytest.skip("platformio not importable in this interpreter")
    from platformio.project.options import ProjectOptions

    known = {key.split(".", 1)[1] for key in ProjectOptions if key.startswith("env.")}
    unknown = [
        k
        for k in apm_env
        if k not in known and not k.startswith(("board_build.", "board_upload.", "custom_"))
    ]
    assert not unknown, f"options PlatformIO does not know: {unknown}"


def test_ini_matches_makefile_defaults(apm_env) -> None:
    makefile = (FIRMWARE / "Makefile").read_text()
    version = re.search(r"^FW_VERSION\s*\?=\s*(\d+)\.(\d+)\.(\d+)", makefile, re.M)
    baud = re.search(r"^BAUD\s*\?=\s*(\d+)", makefile, re.M)
    assert version and baud
    flags = apm_env["build_flags"]
    for part, value in zip(("MAJOR", "MINOR", "PATCH"), version.groups(), strict=True):
        assert f"-DFW_VERSION_{part}={value}" in flags
    assert f"-DUART_BAUD={baud.group(1)}UL" in flags
    for flag in ("-Wall", "-Wextra", "-Werror"):
        assert flag in flags
    assert apm_env["monitor_speed"] == int(baud.group(1))
