"""The builds: ``make`` with a lock, for the firmware (shared by flashing and the emulator) and
for the emulator itself.

The sources are found by :func:`find_firmware_dir` (a checkout's ``firmware/``, the copy an
installed package carries, or ``$IMU_BENCH_FIRMWARE``). One build of them for the whole host:
:mod:`host.board.flash` flashes its hex, :mod:`host.bench.emulator` runs its ELF.
``firmware/emulator/apm_emu`` (C, on libsimavr) and its harness self-test app are built on
demand into ``firmware/build/emulator/`` (for an installed copy: in the user's cache); make
rebuilds what is older than its sources; :func:`toolchain_problem` says in one line what is
missing.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import shutil
import site
import subprocess
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path

from host.errors import UserError

#: a firmware source tree to use instead of the one found (a checkout's, an installed copy's)
FIRMWARE_ENV = "IMU_BENCH_FIRMWARE"


def find_firmware_dir() -> Path:
    """The firmware sources (``Makefile``, ``src/``, ``emulator/``): ``$IMU_BENCH_FIRMWARE``,
    else the checkout's ``firmware/`` beside ``host/``, else the copy ``pip install`` puts in
    ``PREFIX/share/imu-bench/firmware`` (the environment's, then the user's)."""
    if os.environ.get(FIRMWARE_ENV):
        return Path(os.environ[FIRMWARE_ENV])
    checkout = Path(__file__).resolve().parents[2] / "firmware"
    if (checkout / "Makefile").is_file():
        return checkout
    for prefix in (sys.prefix, site.getuserbase()):
        installed = Path(prefix) / "share" / "imu-bench" / "firmware"
        if (installed / "Makefile").is_file():
            return installed
    return checkout  # missing: make says so, and the error names FIRMWARE_ENV


def default_build_dir(firmware: Path) -> Path:
    """Where builds go: ``firmware/build`` when that is writable (a checkout), else the
    user's cache (an installed copy): ``$XDG_CACHE_HOME/imu-bench/build``."""
    if os.access(firmware, os.W_OK):
        return firmware / "build"
    cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return cache / "imu-bench" / "build"


FIRMWARE_DIR = find_firmware_dir()
DEFAULT_BUILD = default_build_dir(FIRMWARE_DIR)
HEX_NAME = "imu_bench.hex"
EMULATOR_SRC = FIRMWARE_DIR / "emulator"
DEFAULT_EMU_BUILD = DEFAULT_BUILD / "emulator"
MISSING = "emu:// needs simavr: apt-get install simavr libsimavr-dev gcc-avr avr-libc"
SIMAVR_HEADER = Path("/usr/include/simavr/sim_avr.h")


@contextlib.contextmanager
def build_lock(build_dir: Path) -> Iterator[None]:
    """Serialise builds of one directory between processes (parallel tests, two boards)."""
    build_dir.mkdir(parents=True, exist_ok=True)
    with open(build_dir / ".build.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def build_firmware_hex(build_dir: str | Path | None = None, make_args: Sequence[str] = ()) -> Path:
    """``make -C firmware BUILD=dir [VAR=value ...]`` (make rebuilds only what changed); return
    the path of ``imu_bench.hex`` (``imu_bench.elf`` is beside it). The one firmware build of
    the host: :func:`build_firmware` (the ELF, for the emulator) uses it too."""
    for tool in ("make", "avr-g++", "avr-objcopy"):
        if shutil.which(tool) is None:
            raise UserError(
                f"building the firmware needs {tool}: apt-get install gcc-avr avr-libc "
                "binutils-avr make (or give a ready --hex FILE)"
            )
    out = Path(build_dir) if build_dir else DEFAULT_BUILD
    with build_lock(out):
        r = subprocess.run(
            ["make", "--no-print-directory", "-C", str(FIRMWARE_DIR), f"BUILD={out.resolve()}",
             *make_args],
            capture_output=True,
            text=True,
        )  # fmt: skip
    if r.returncode != 0:
        tail = (r.stdout + r.stderr).strip().splitlines()[-1:] or ["?"]
        where = "" if (FIRMWARE_DIR / "Makefile").is_file() else (
            f"; no firmware sources in {FIRMWARE_DIR}: set {FIRMWARE_ENV} to a firmware/ "
            "directory (or give a ready --hex FILE)"
        )  # fmt: skip
        raise UserError(f"building the firmware failed (make -C firmware): {tail[0]}{where}")
    hex_path = out / HEX_NAME
    if not hex_path.exists():
        raise UserError(f"building the firmware did not produce {hex_path}")
    return hex_path


def toolchain_problem(need_avr: bool = True) -> str | None:
    """None when the emulator can be built and run here, else the one-line reason."""
    if not SIMAVR_HEADER.exists() or shutil.which("cc") is None or shutil.which("make") is None:
        return MISSING
    libs = ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib", "/usr/local/lib")
    if not any(Path(d, "libsimavr.so").exists() or Path(d, "libsimavr.a").exists() for d in libs):
        return MISSING
    if need_avr and shutil.which("avr-gcc") is None:
        return MISSING
    return None


def require_toolchain(need_avr: bool = True) -> None:
    problem = toolchain_problem(need_avr)
    if problem:
        raise UserError(problem)


def _make(args: Sequence[str], what: str) -> None:
    r = subprocess.run(["make", "--no-print-directory", *args], capture_output=True, text=True)
    if r.returncode != 0:
        tail = "\n".join((r.stdout + r.stderr).strip().splitlines()[-15:])
        raise UserError(f"building {what} failed:\n{tail}")


def build_emulator(build_dir: str | Path | None = None) -> Path:
    """Build ``apm_emu`` (make decides whether the sources are newer) and return its path."""
    require_toolchain(need_avr=False)
    out = Path(build_dir) if build_dir else DEFAULT_EMU_BUILD
    with build_lock(out):
        _make(["-C", str(EMULATOR_SRC), f"BUILD={out.resolve()}"], "the emulator")
    return out / "apm_emu"


def build_testapp(build_dir: str | Path | None = None) -> tuple[Path, Path]:
    """Build the harness self-test firmware: (good, bad) ELF paths (see testapp/testapp.c)."""
    require_toolchain(need_avr=True)
    out = Path(build_dir) if build_dir else DEFAULT_EMU_BUILD
    with build_lock(out):
        _make(["-C", str(EMULATOR_SRC), "testapp", f"BUILD={out.resolve()}"], "the test app")
    return out / "testapp.elf", out / "testapp_bad.elf"


def build_firmware(build_dir: str | Path | None = None, make_args: Sequence[str] = ()) -> Path:
    """Build the real firmware (``make -C firmware BUILD=dir``) and return ``dir/imu_bench.elf``.

    ``make_args`` are extra make variables, e.g. ``["BAUD=500000"]``.
    """
    require_toolchain(need_avr=True)
    elf = build_firmware_hex(build_dir, make_args).with_suffix(".elf")
    if not elf.exists():
        raise UserError(f"building the firmware did not produce {elf}")
    return elf
