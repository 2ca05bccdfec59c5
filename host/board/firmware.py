"""The firmware build: ``make -C firmware`` with a lock, shared by flashing and the emulator.

One build of ``firmware/`` for the whole host: :mod:`host.board.flash` flashes its hex,
:mod:`host.bench.emulator` runs its ELF.
"""

from __future__ import annotations

import contextlib
import fcntl
import shutil
import subprocess
from collections.abc import Iterator, Sequence
from pathlib import Path

from host.errors import UserError

ROOT = Path(__file__).resolve().parents[2]
FIRMWARE_DIR = ROOT / "firmware"
DEFAULT_BUILD = FIRMWARE_DIR / "build"
HEX_NAME = "imu_bench.hex"


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
    the host: :func:`host.bench.emulator.build_firmware` uses it too."""
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
        raise UserError(f"building the firmware failed (make -C firmware): {tail[0]}")
    hex_path = out / HEX_NAME
    if not hex_path.exists():
        raise UserError(f"building the firmware did not produce {hex_path}")
    return hex_path
