"""``python3 -m host`` runs numpy's BLAS on one thread unless the user asks otherwise (issue 31:
on a loaded 2-core machine a thread per core made ``model add`` 20x slower)."""

from __future__ import annotations

import os
import struct
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# what the command's process sees once the command line is loaded (numpy imported with it)
_PROBE = r"""
import os, runpy, sys
sys.argv = ["host", "--version"]
try:
    runpy.run_module("host", run_name="__main__")
except SystemExit:
    pass
import numpy  # as a command's module imports it, after the command line set the variables
print(os.environ.get("OPENBLAS_NUM_THREADS"), os.environ.get("OMP_NUM_THREADS"),
      os.environ.get("MKL_NUM_THREADS"), len(os.listdir("/proc/self/task")), file=sys.stderr)
"""


def _probe(env_extra: dict[str, str]) -> list[str]:
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    env.update(env_extra)
    env["PYTHONPATH"] = str(ROOT)
    run = subprocess.run(
        [sys.executable, "-c", _PROBE], cwd=ROOT, env=env, capture_output=True, text=True,
        timeout=120,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    return run.stderr.strip().splitlines()[-1].split()


def test_the_command_line_pins_the_blas_to_one_thread() -> None:
    openblas, omp, mkl, threads = _probe({})
    assert (openblas, omp, mkl) == ("1", "1", "1")
    # numpy's OpenBLAS would have started a thread per core beyond the first
    assert int(threads) == 1


def test_a_users_own_thread_count_is_kept() -> None:
    openblas, omp, mkl, _ = _probe({"OPENBLAS_NUM_THREADS": "2", "OMP_NUM_THREADS": "3"})
    assert (openblas, omp, mkl) == ("2", "3", "1")


def test_start_up_imports_only_what_the_command_needs(tmp_path: Path) -> None:
    """``decode`` and ``capture`` load neither the fit, the archive nor scipy (they did: every
    command's module was imported to build the parser, 1 090 modules for ``capture``)."""
    code = (
        "import sys\nfrom host.__main__ import main\n"
        "for argv in (['decode', sys.argv[1]], ['capture', '--port', 'sim://', sys.argv[1]]):\n"
        "    try:\n        main(argv)\n    except SystemExit:\n        pass\n"
        "heavy = ('scipy', 'sqlalchemy', 'host.archive', 'host.calib', 'host.workbench')\n"
        "print(sorted({m for m in sys.modules if m.startswith(heavy)}))\n"
    )
    cap = tmp_path / "exists.cap"
    cap.write_bytes(b"")
    root = Path(__file__).resolve().parents[2]
    done = subprocess.run(
        [sys.executable, "-c", code, str(cap)], capture_output=True, text=True, cwd=root,
        timeout=120,
    )  # fmt: skip
    assert done.stdout.strip().splitlines()[-1] == "[]", done.stdout + done.stderr


def test_decode_loads_the_clock_map_only_for_a_capture_with_arrival_times(
    tmp_path: Path,
) -> None:
    """``decode --stats`` of a raw capture imports neither the clock map (host.timing) nor the
    CSV writer; of an IMUCAP01 capture, the clock map."""
    code = (
        "import sys\nfrom host.__main__ import main\n"
        "main(['decode', '--stats', sys.argv[1]])\n"
        "print(sorted(m for m in ('host.timing', 'csv') if m in sys.modules))\n"
        "main(['decode', '--stats', sys.argv[2]])\n"
        "print(sorted(m for m in ('host.timing', 'csv') if m in sys.modules))\n"
    )
    from host.wire.capture import MAGIC

    raw, cap = tmp_path / "raw.bin", tmp_path / "arrivals.cap"
    raw.write_bytes(bytes(100))
    cap.write_bytes(MAGIC + struct.pack("<QI", 10**9, 100) + bytes(100))  # one read
    root = Path(__file__).resolve().parents[2]
    done = subprocess.run(
        [sys.executable, "-c", code, str(raw), str(cap)], capture_output=True, text=True,
        cwd=root, timeout=120,
    )  # fmt: skip
    lines = [x for x in done.stdout.splitlines() if x.startswith("[")]
    assert lines == ["[]", "['host.timing']"], done.stdout + done.stderr


def test_a_value_starting_with_a_minus_names_the_equals_form() -> None:
    """Was: 'argument --axes: expected one argument' for --axes -x,-y,z, with no way out."""
    from tests.host.cli.cli_run import run

    rc, _, err = run(["export", "R", "--to", "px4", "--axes", "-x,-y,z"])
    assert rc == 2 and err.count("\n") == 1
    assert "a value starting with '-' goes as --axes=VALUE" in err
    rc, _, err = run(["plan", "D", "--top"])  # a value left out: the same words are true
    assert rc == 2 and "--top=VALUE" in err


def test_an_empty_word_is_never_read_as_the_current_directory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Was: ``import FILE --out "$UNSET"`` wrote the records into the current directory and
    ``plan ""`` read it ('' is a path to '.'); an empty word is an unset variable, most often."""
    from tests.host.cli.cli_run import run

    monkeypatch.chdir(tmp_path)
    for argv, words in (
        (["import", "x.cap", "--serial", "S1", "--out", ""], "--out '': an empty value"),
        (["import", "x.cap", "--serial", "S1", "--out="], "--out '': an empty value"),
        (["calibrate", "--from-dir", "", "--no-archive"], "--from-dir '': an empty value"),
        (["plan", ""], "'': an empty argument (an unset variable?)"),
        (["archive", "show", "", "--archive", "a.sqlite"], "'': an empty argument"),
    ):
        rc, out, err = run(argv)
        assert rc == 2 and words in err and err.count("\n") == 1, (argv, err)
    assert list(tmp_path.iterdir()) == []  # nothing written anywhere
