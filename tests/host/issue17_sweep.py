"""The bad inputs of issue 17's sweep and issue 31's (its second round, on the commands of
the last waves: tests/host/issue31_sweep.py), as a user types them: each case builds
its files in a fresh directory and names the command, the exit codes it may give and the words
its message must hold. ``tests/host/test_issue17_sweep.py`` runs them in-process on every CI
run; run them as real processes (what a user sees, Python's own tracebacks included) with::

    python3 -m tests.host.issue17_sweep [--only NAME]

which prints one line per case (exit code, seconds, the message's last line) and exits 1 when
any case gives a traceback, an exit code outside 0/1/2 (130 for Ctrl+C), the wrong code, no
one-line reason, or takes longer than its bound.

What needs an emulated board (``emu://?fault=no-drdy|absent|stuck-miso`` under ``--yes``) is in
tests/emulator/test_emu_faults.py; a full disk needs an injected or a real small file system:
tests/host/calib/test_report_publication.py and dialogue/test_flow_faults.py.
"""

from __future__ import annotations

import argparse
import os
import signal
import struct
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class Case:
    """One bad input: ``make(dir)`` builds the files and returns the command's arguments."""

    name: str
    why: str  # the issue's words for it
    make: Callable[[Path], list[str]]
    codes: tuple[int, ...]  # exit codes it may give
    words: str = ""  # must appear in stderr
    bound_s: float = 60.0
    interrupt_after_s: float | None = None  # send Ctrl+C after this long (endless input)
    feed_fifo: bool = False  # make() made DIR/fifo: a writer process feeds it DIR/fifo.src
    out_words: str = ""  # must appear in stdout
    width: bool = False  # stderr within 80 columns but for a single word (a path)
    process: bool = False  # only a real process shows it (its own end, a closed pipe)
    head_lines: int | None = None  # stdout closed after this many lines (as '| head -N')


# --------------------------------------------------------------------------- inputs


def _imu(seq: int, t_us: int) -> bytes:
    from host.wire.frames import encode_frame

    return encode_frame(
        "IMU_SAMPLE", seq, t_us=t_us, ax=10, ay=-20, az=16000, temp=300, gx=1, gy=-2, gz=3, flags=0
    )


def _cap(d: Path, reads: list[tuple[int, bytes]], name: str = "x.cap") -> Path:
    from host.wire.capture import MAGIC

    p = d / name
    p.write_bytes(MAGIC + b"".join(struct.pack("<QI", t, len(b)) + b for t, b in reads))
    return p


def _session(d: Path, serial: str = "Q1", turns: int = 1) -> Path:
    from host.bench.plan import Plan, simulate_session, write_session
    from host.bench.truth import SensorTruth

    out = d / serial
    truth = SensorTruth.random(np.random.default_rng(4))
    write_session(
        out, serial, simulate_session(truth, Plan(static_s=3.0, turns=turns, warmup_s=0), 4)
    )
    return out


def _hello_bad_codes(d: Path) -> list[str]:
    from host.bench.firmware import hello_fields
    from host.wire.frames import encode_frame

    fields = hello_fields() | {"accel_fs_sel": 7, "gyro_fs_sel": 0}
    p = d / "hello.bin"
    p.write_bytes(encode_frame("HELLO", 0, **fields) + _imu(1, 1000))
    return ["decode", str(p)]


def _term(d: Path, name: str, body: str) -> Path:
    f = d / f"{name}_terms.py"
    f.write_text(
        "import numpy as np\nfrom host.model.terms import term\n\n"
        f"@term(sensors=('gyro',))\ndef {name}(sig, sensor, axis):\n"
        f"    '''A user term.'''\n    {body}\n"
    )
    return f


def _one_row(d: Path) -> list[str]:
    s = _session(d)
    rec = s / "Q1_y_dn.txt"
    lines = rec.read_text().splitlines()
    head = [x for x in lines if x.startswith("#")]
    row = next(x for x in lines if x and x[0].isdigit())
    vals = row.split("\t")[1:]
    rec.write_text("\n".join([*head, row, "_" * 40, "mean\t" + "\t".join(vals),
                              "std\t" + "\t".join(["0"] * 7)]))  # fmt: skip
    return ["calibrate", "--from-dir", str(s)]


def _dangling(d: Path) -> list[str]:
    s = _session(d)
    (s / "Q1_z_cw.txt").unlink()
    (s / "Q1_z_cw.txt").symlink_to(d / "gone.txt")
    return ["calibrate", "--from-dir", str(s)]


def _dir_record(d: Path) -> list[str]:
    s = _session(d)
    (s / "Q1_z_cw.txt").unlink()
    (s / "Q1_z_cw.txt").mkdir()
    return ["calibrate", "--from-dir", str(s)]


def _diagnose_one(d: Path) -> list[str]:
    s = _session(d)
    one = d / "one"
    one.mkdir()
    (one / "Q1_x_up.txt").write_bytes((s / "Q1_x_up.txt").read_bytes())
    return ["model", "diagnose", str(one)]


def _failed_sensor(d: Path) -> list[str]:
    from host.wire.frames import encode_frame

    board = d / "failed.bin"
    board.write_bytes(
        b"".join(encode_frame("ERROR", k, code=6, detail=1, count=k + 1) for k in range(5))
    )
    return ["capture", "--port", f"replay://{board}?speed=max", "--seconds", "0.5",
            str(d / "o.cap")]  # fmt: skip


def _host_type_frame(d: Path) -> list[str]:
    from host.wire.frames import _envelope

    p = d / "b8.bin"
    p.write_bytes(_imu(0, 1000) + _envelope(0xB8, 1, b"\x00" * 4) + _imu(2, 21000))
    return ["decode", "--stats", str(p)]


def _fifo(d: Path) -> list[str]:
    (d / "fifo.src").write_bytes(b"".join(_imu(k, 1000 + 20_000 * k) for k in range(500)))
    os.mkfifo(d / "fifo")
    return ["decode", "--csv", str(d / "fifo")]


def _results_under_a_file(d: Path) -> list[str]:
    s = _session(d)
    (d / "afile").write_text("x")
    return ["calibrate", "--from-dir", str(s), "--out", str(d / "afile" / "out")]


def _not_an_elf(d: Path) -> list[str]:
    (d / "fw.elf").write_text("not firmware")
    return ["capture", "--port", f"emu://?elf={d / 'fw.elf'}", "--seconds", "1", str(d / "o.cap")]


def _truncated_capture(d: Path) -> list[str]:
    p = _cap(d, [(10**9 + k * 10**6, _imu(k, 1000 + 20_000 * k)) for k in range(50)])
    p.write_bytes(p.read_bytes()[:-9])
    return ["decode", "--stats", str(p)]


def _existing_capture(d: Path) -> list[str]:
    (d / "old.cap").write_bytes(b"IMUCAP01 an earlier recording")
    return ["capture", "--port", "sim://?speed=max", "--seconds", "0.5", str(d / "old.cap")]


def _resume_over_a_capture(d: Path) -> list[str]:
    (d / "old.cap").write_bytes(b"IMUCAP01 an earlier recording")
    return ["calibrate", "--serial", "Q1", "--out", str(d / "Q1"), "--yes", "--resume",
            "--static-seconds", "2", "--warmup", "0", "--capture", str(d / "old.cap")]  # fmt: skip


def _flipped_length(d: Path) -> list[str]:
    reads = [(10**12 + k * 20_000_000, _imu(k, 1000 + 20_000 * k)) for k in range(200)]
    p = _cap(d, reads)
    raw = bytearray(p.read_bytes())
    raw[8 + 60 * (12 + len(reads[0][1])) + 11] ^= 0x40  # read 60's length: 1 GiB
    p.write_bytes(bytes(raw))
    return ["decode", "--stats", str(p)]


def _foreign_hello(d: Path) -> list[str]:
    from host.bench.firmware import hello_fields
    from host.wire.frames import encode_frame

    fields = hello_fields() | {"spec_fingerprint": 0x1234}
    p = d / "foreign.bin"
    p.write_bytes(encode_frame("HELLO", 0, **fields) + _imu(1, 1000))
    return ["decode", str(p)]


def _endless_term(d: Path) -> list[str]:
    s = _session(d)
    f = _term(d, "spin", "while True: pass")
    return ["model", "add", str(s), "spin:gyro", "--term-file", str(f), "--term-timeout", "2"]


def _not_a_database(d: Path) -> list[str]:
    (d / "notes.db").write_text("the bench's notes, not an archive\n")
    return ["archive", "list", "--archive", str(d / "notes.db")]


def _binary_result(d: Path) -> list[str]:
    (d / "S_result.json").write_bytes(bytes(range(256)) * 4)
    return ["archive", "add", str(d / "S_result.json"), "--archive", str(d / "a.sqlite")]


def _lot_not_there(d: Path) -> list[str]:
    from host.archive.store import Archive

    Archive(str(d / "a.sqlite")).close()  # an archive, without that lot
    return ["archive", "lot", "L7-TYPO", "--archive", str(d / "a.sqlite")]


CASES: tuple[Case, ...] = (
    Case("sim-speed-inf", "sim://?speed=inf spins at 100 % CPU",
         lambda d: ["capture", "--port", "sim://?speed=inf", "--seconds", "1", str(d / "o.cap")],
         (2,), "speed='inf' is outside"),
    Case("sim-clock-ppm", "clock_ppm=1e9 spins at 100 % CPU",
         lambda d: ["capture", "--port", "sim://?clock_ppm=1e9", "--seconds", "1",
                    str(d / "o.cap")], (2,), "clock_ppm='1e9' is outside"),
    Case("decode-fifo", "decoding a FIFO blocks", _fifo, (0,), "waiting for a writer",
         feed_fifo=True),
    Case("decode-dev-zero", "decode /dev/zero: unbounded read, MemoryError",
         lambda d: ["decode", "--stats", "/dev/zero"], (130,), "reading the device /dev/zero",
         interrupt_after_s=3.0),
    Case("decode-dir", "a directory where a capture belongs",
         lambda d: ["decode", str(d)], (2,), "is a directory"),
    Case("hello-codes", "HELLO full-scale codes out of range: KeyError: 7", _hello_bad_codes,
         (2,), "full-scale codes AFS_SEL 7"),
    Case("samples-61s-apart", "two samples 61 s apart: need at least one array to stack",
         lambda d: ["decode", str(_cap(d, [(10**9, _imu(0, 5_000_000)),
                                          (62 * 10**9, _imu(1, 66_000_000))]))], (0,),
         out_words='"t_host_ns": 6199765'),
    Case("nonsense-arrivals", "arrival times giving -1 000 000 ppm with no warning",
         lambda d: ["decode", "--stats",
                    str(_cap(d, [(7, _imu(k, 1000 + 20_000 * k)) for k in range(200)]))],
         (0,), "the device clock runs -1000000 ppm"),
    Case("truncated-capture", "a capture cut off mid-read (killed recording)",
         _truncated_capture, (0,), "cut-off read"),
    Case("host-type-frame", "a CRC-valid frame of host type 0xB8 in a board's stream",
         _host_type_frame, (0,), out_words='"frames": 2, "crc_errors": 0'),
    Case("term-shadows-bias", "a term file redefining bias replaces the built-in",
         lambda d: ["model", "diagnose", str(_session(d)), "--term-file",
                    str(_term(d, "bias", "return sig.temp_c"))], (2,),
         "has the name of a built-in term"),
    Case("term-returns-nan", "a term returning NaN is added with RMS z nan",
         lambda d: ["model", "add", str(_session(d)), "wob:gyro", "--term-file",
                    str(_term(d, "wob", "return np.full(len(sig.t_s), np.nan)"))], (2,),
         "non-finite values"),
    Case("term-raises", "a user term that raises: traceback",
         lambda d: ["model", "add", str(_session(d)), "wob:gyro", "--term-file",
                    str(_term(d, "wob", "raise RuntimeError('my bug')"))], (2,),
         "raised RuntimeError: my bug"),
    Case("turns-contradict", "--turns contradicting the records' header is ignored",
         lambda d: ["calibrate", "--from-dir", str(_session(d)), "--turns", "3"], (2,),
         "--turns 3, but record"),
    Case("dangling-link", "dangling symlinks named like records are skipped", _dangling, (2,),
         "a broken link"),
    Case("dir-record", "directories named like records are skipped", _dir_record, (2,),
         "a directory, named like a record"),
    Case("one-row-record", "a one-row static record is accepted", _one_row, (2,), "1 data row"),
    Case("diagnose-one-record", "model diagnose on one record says adequate", _diagnose_one,
         (2,), "no degrees of freedom"),
    Case("capture-failed-sensor", "capture on a failed sensor exits 0 with 0 samples",
         _failed_sensor, (2,), "the board's sensor failed"),
    Case("emu-not-an-elf", "emu://?elf=<not an ELF> says the board disconnected",
         _not_an_elf, (2,), "not an ELF or Intel HEX file"),
    Case("results-under-a-file", "results written where a file blocks the directory",
         _results_under_a_file, (2,), "afile is a file; give --out a directory"),
    # issue 31
    Case("capture-over-a-file", "capture FILE overwrites an earlier capture",
         _existing_capture, (2,), "never overwritten"),
    Case("resume-over-a-capture", "--resume --capture FILE overwrites an earlier capture",
         _resume_over_a_capture, (2,), "never overwritten"),
    Case("capture-flipped-length", "one flipped bit in a read's length loses the rest",
         _flipped_length, (0,), "1 damaged place(s) in the file", out_words='"frames": 199'),
    Case("hello-of-another-spec", "a HELLO of another spec is dropped, default scales used",
         _foreign_hello, (2,), "spec 0x00001234)"),
    Case("endless-term", "a term file with an endless loop runs with no output, no bound",
         _endless_term, (2,), "give --term-timeout S", bound_s=30.0),
    Case("archive-not-a-database", "a text file as --archive: sqlite3.DatabaseError traceback",
         _not_a_database, (2,), "file is not a database"),
    Case("archive-binary-result", "archive add of a binary file: UnicodeDecodeError traceback",
         _binary_result, (2,), "not UTF-8 text"),
    Case("archive-lot-not-there", "archive lot of a lot not in the archive exits 0 (passed)",
         _lot_not_there, (2,), "no calibration in lot L7-TYPO"),
)  # fmt: skip


# --------------------------------------------------------------------------- checking


def check(case: Case, rc: int, err: str, took: float, out: str = "") -> list[str]:
    """What is wrong with one run (empty: nothing)."""
    bad = []
    if case.out_words and case.out_words not in out:
        bad.append(f"output lacks {case.out_words!r}")
    if "Traceback" in err or "Exception ignored" in err:
        bad.append("traceback")
    if rc not in case.codes:
        bad.append(f"exit {rc}, expected {case.codes}")
    if case.words and case.words not in err:
        bad.append(f"message lacks {case.words!r}")
    if rc == 2 and not any(x.startswith("error:") for x in err.splitlines()):
        bad.append("exit 2 without an 'error:' line")
    if took > case.bound_s:
        bad.append(f"took {took:.0f} s > {case.bound_s:.0f} s")
    if case.width:
        from tests.host.cli.cli_run import too_wide

        bad += [f"wider than 80 columns: {ln[:60]}…" for ln in too_wide(err)]
    if case.words and case.words not in err and case.words in " ".join(err.split()):
        bad.remove(f"message lacks {case.words!r}")  # the words, wrapped at a space
    return bad


def run_process(case: Case, d: Path) -> tuple[int, str, float, str]:
    """Run the case as ``python3 -m host ...`` in its own process."""
    argv = case.make(d)
    feeder = None
    if case.feed_fifo:
        feeder = subprocess.Popen(["sh", "-c", 'cat "$1" > "$2"', "sh", str(d / "fifo.src"),
                                   str(d / "fifo")])  # fmt: skip
    t0 = time.monotonic()
    p = subprocess.Popen([sys.executable, "-m", "host", *argv], cwd=ROOT, text=True,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    try:
        head = ""
        if case.interrupt_after_s is not None:  # Ctrl+C once it runs (not while Python starts)
            assert p.stderr is not None
            while case.words not in head and p.poll() is None:
                head += p.stderr.readline()
            time.sleep(case.interrupt_after_s)
            p.send_signal(signal.SIGINT)
        if case.head_lines is not None:  # as '| head -N': read N lines, then close the pipe
            out, err = _head(p, case.head_lines, case.bound_s * 2)
        else:
            out, err = p.communicate(timeout=case.bound_s * 2)
        err = head + err
    except subprocess.TimeoutExpired:
        p.kill()
        out, err = p.communicate()
        err += "\n(killed: no end in sight)"
    if feeder is not None:
        feeder.wait(timeout=10)
    return p.returncode, err, time.monotonic() - t0, out


def _head(p: subprocess.Popen[str], lines: int, timeout: float) -> tuple[str, str]:
    """Read ``lines`` lines of ``p``'s stdout and close it, as ``| head -N`` does; then its
    stderr to the end."""
    assert p.stdout is not None and p.stderr is not None
    out = "".join(p.stdout.readline() for _ in range(lines))
    p.stdout.close()
    err = p.stderr.read()
    p.wait(timeout=timeout)
    return out, err


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", help="run only the case of this name")
    args = ap.parse_args()
    from tests.host.issue31_sweep import CASES as WAVE  # the second round's input kinds
    from tests.host.issue44_sweep import CASES as RULES  # issue 44: one rule for every input

    failed = ran = 0
    for case in (*CASES, *WAVE, *RULES):
        if args.only and case.name != args.only:
            continue
        ran += 1
        with tempfile.TemporaryDirectory() as tmp:
            rc, err, took, out = run_process(case, Path(tmp))
        bad = check(case, rc, err, took, out)
        failed += bool(bad)
        last = (err.strip().splitlines() or [""])[-1][:110]
        mark = "FAIL " + "; ".join(bad) if bad else "ok"
        print(f"{case.name:<22} exit {rc:<3} {took:5.1f} s  {mark}\n    {last}", flush=True)
    print(f"{failed} of {ran} cases failed" if failed else f"all {ran} cases ok")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
