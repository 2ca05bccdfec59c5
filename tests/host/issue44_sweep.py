"""The cases of issue 44: one rule for what every command accepts — a serial that is never more
than one line of a file, a wire that names what it cannot read, inputs within bounds, nothing
replaced silently, a term file's process ending a failure, every command reading what another
wrote. The cases are :class:`tests.host.issue17_sweep.Case`: ``tests/host/test_issue17_sweep.py``
runs them on every CI run and ``python3 -m tests.host.issue17_sweep`` as real processes, with
issue 17's and 31's.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path

from tests.host.issue17_sweep import Case, _session, _term
from tests.host.issue31_sweep import _calibrated

#: the serial of the issue: a C comment's end, a function, a line break, an ArduPilot parameter
EVIL = "Q1 */ int evil(void){return 1;} /*\nARMING_CHECK 0"
#: the record files' serial of the issue (a file name may hold any byte but '/' and NUL)
EVIL_NAME = "Q1\nARMING_CHECK 0\n#"
MARKUP = 'X"><svg onload=alert(1)>'


# --------------------------------------------------------------------------- 1. the serial


def _result_with_serial(d: Path, serial: str) -> Path:
    """A calibrated session whose result JSON says ``serial``."""
    s = _calibrated(d)
    doc = json.loads((s / "Q1_result.json").read_text())
    (s / "Q1_result.json").write_text(json.dumps({**doc, "serial": serial}))
    return s / "Q1_result.json"


def _renamed(d: Path, serial: str) -> Path:
    """A session whose record files are named ``serial_name.txt`` (headers without serial)."""
    s = _session(d)
    for p in sorted(s.glob("Q1_*.txt")):
        text = "".join(ln for ln in p.read_text().splitlines(True) if ln != "# serial: Q1\n")
        (s / (serial + p.name[2:])).write_text(text)
        p.unlink()
    return s


def _export_evil(d: Path, to: str) -> list[str]:
    return ["export", str(_result_with_serial(d, EVIL)), "--to", to, "--allow-fail"]


# --------------------------------------------------------------------------- 2. the wire


def _hello(d: Path, length: int = 23, who: int = 0x68, again: int | None = None) -> list[str]:
    """A CRC-valid HELLO of ``length`` payload bytes (the spec's: 23) announcing ±16 g, then
    samples of 1 g (2048 counts at ±16 g); ``again``: a second HELLO of WHO_AM_I ``again`` in
    the middle."""
    from host.bench.firmware import hello_fields
    from host.wire.frames import HEADER_LEN, _envelope, encode_frame

    def hello(seq: int, who: int) -> bytes:
        payload = encode_frame("HELLO", seq, **(hello_fields() | {"accel_fs_sel": 3,
                                                                  "who_am_i": who}))  # fmt: skip
        body = payload[HEADER_LEN:-2]
        body = body[:length] + bytes(max(0, length - len(body)))
        return _envelope(payload[2], seq, body)

    frames = [hello(0, who)] + [_imu(k, 1000 + 20_000 * k, az=2048) for k in range(1, 6)]
    if again is not None:
        frames += [hello(6, again)] + [_imu(k, 1000 + 20_000 * k, az=2048) for k in range(7, 9)]
    p = d / "hello.bin"
    p.write_bytes(b"".join(frames))
    return ["decode", str(p)]


def _imu(seq: int, t_us: int, az: int) -> bytes:
    from host.wire.frames import encode_frame

    return encode_frame("IMU_SAMPLE", seq, t_us=t_us, ax=0, ay=0, az=az, temp=300, gx=0, gy=0,
                        gz=0, flags=0)  # fmt: skip


def _read_written_twice(d: Path) -> list[str]:
    """A capture whose fifth read is written twice (the same arrival time and bytes)."""
    from tests.host.issue17_sweep import _cap
    from tests.host.issue17_sweep import _imu as imu

    reads = [(10**9 + k * 20_000_000, imu(k, 1000 + 20_000 * k)) for k in range(10)]
    return ["decode", str(_cap(d, [*reads[:5], reads[4], *reads[5:]]))]


# --------------------------------------------------------------------------- 3. bounds


def _deep(d: Path, name: str = "deep.json") -> Path:
    p = d / name
    p.write_text("[" * 100_000)
    return p


def _archive_add_deep(d: Path) -> list[str]:
    s = _session(d)
    _deep(s, "Q1_result.json")
    (s / "Q1_result.txt").write_text("report\n")
    return ["archive", "add", str(s), "--archive", str(d / "a.sqlite")]


# --------------------------------------------------------------------------- 4. replaced


#: locks a case holds for its whole run (as a live session in the directory would)
_HELD: list[object] = []


def _locked(d: Path) -> Path:
    """``d`` locked as a live session locks its directory (another open file: the command's
    own lock meets it as another process's would)."""
    from host.session.directory import lock_directory

    d.mkdir(parents=True, exist_ok=True)
    _HELD.append(lock_directory(d, "calibrate --serial Q1 (a live session)"))
    return d


def _earlier_result_of_other_records(d: Path) -> list[str]:
    """A result in ``a/Q1`` of its records; other records of Q1 (another sitting) in ``b/Q1``,
    computed into ``a/Q1``."""
    out = _calibrated(d / "a")
    other = _session(d / "b")
    (other / "Q1_x_up.txt").write_text((other / "Q1_x_up.txt").read_text() + "\n")
    return ["calibrate", "--from-dir", str(other), "--out", str(out), "--no-archive"]


# --------------------------------------------------------------------------- 6. each other's


def _noise_of_a_bare_record(d: Path) -> list[str]:
    """A static record in the method's format: no '#' header (as calibrate --from-dir reads)."""
    p = _session(d) / "Q1_z_up.txt"
    p.write_text("".join(ln for ln in p.read_text().splitlines(True) if not ln.startswith("#")))
    return ["noise", str(p)]


def _session_with_warmup(d: Path) -> list[str]:
    """A dialogue's session: its records (statics of 3 s, each shorter than the 20 s window)
    and its warm-up, 15 min with x up from 25 to 35 °C, the bias rising 2 mg/°C."""
    import numpy as np

    from host.session.directory import read_record, write_record
    from host.session.records import Record

    s = _session(d)
    up = read_record(s / "Q1_x_up.txt")
    t_ms = np.arange(9000) * 100.0
    temp = 35.0 - 10.0 * np.exp(-t_ms / 300_000.0)
    rng = np.random.default_rng(7)
    accel = np.tile(up.accel.mean(axis=0), (9000, 1)) + rng.normal(0, 0.01, (9000, 3))
    accel[:, 0] += 0.0196 * (temp - 25.0)
    gyro = np.tile(up.gyro.mean(axis=0), (9000, 1)) + rng.normal(0, 0.02, (9000, 3))
    meta = {**up.meta, "kind": "warmup", "record": "warmup"}
    write_record(s / "Q1_warmup.txt", Record("warmup", t_ms, accel, gyro, temp, meta))
    return ["thermal", str(s)]


# --------------------------------------------------------------------------- 5. term files


def _term_ends(d: Path, body: str, at_load: bool = False) -> list[str]:
    f = _term(d, "bye", "import os; " + body if not at_load else "return sig.t_s")
    if at_load:
        f.write_text("import os\n" + body + "\n" + f.read_text())
    return ["model", "add", str(_session(d)), "bye:gyro", "--term-file", str(f)]


def _edited(d: Path, edit: Callable[[str], str]) -> list[str]:
    """A session whose y_up record's text is ``edit``-ed."""
    s = _session(d)
    p = s / "Q1_y_up.txt"
    p.write_text(edit(p.read_text()))
    return ["calibrate", "--from-dir", str(s), "--no-archive"]


def _times(text: str, f: Callable[[float], str]) -> str:
    """``text`` with each data row's time ``f``-ed."""
    out = []
    for ln in text.splitlines():
        if ln[:1].isdigit() and "\t" in ln:
            t, rest = ln.split("\t", 1)
            ln = f(float(t)) + "\t" + rest
        out.append(ln)
    return "\n".join(out) + "\n"


CASES: tuple[Case, ...] = (
    # 1. one serial rule
    Case("export-serial-line-break", "a result's serial with a line break: ARMING_CHECK 0",
         lambda d: _export_evil(d, "ardupilot"), (2,),
         "not a result this program wrote (its serial"),
    Case("export-serial-c-comment", "a result's serial: a C function in the header",
         lambda d: _export_evil(d, "c-header"), (2,), "not allowed: '\\n'"),
    Case("from-dir-serial-line-break", "records named Q1\\nARMING_CHECK 0\\n#_x_up.txt",
         lambda d: ["calibrate", "--from-dir", str(_renamed(d, EVIL_NAME)), "--no-archive"],
         (2,), "the records' serial number 'Q1\\x0aARMING_CHEC...'"),
    Case("from-dir-serial-markup", "X\"><svg onload=…> passes --from-dir",
         lambda d: ["calibrate", "--from-dir", str(_renamed(d, MARKUP)), "--no-archive"],
         (2,), "not allowed:"),
    # 2. the wire names what it cannot read
    Case("hello-of-24-bytes", "a CRC-valid 24-byte HELLO of ±16 g: az = 1.226 for 9.807",
         lambda d: _hello(d, 24), (2,), "a HELLO with a 24-byte payload, its CRC valid"),
    Case("hello-of-22-bytes", "a CRC-valid 22-byte HELLO: dropped, default scales",
         lambda d: _hello(d, 22), (2,), "(this spec's HELLO has 23)"),
    Case("hello-of-another-sensor", "a mid-stream HELLO of WHO_AM_I 0x12 gets no word",
         lambda d: _hello(d, again=0x12), (2,), "a HELLO of another sensor (WHO_AM_I 0x12"),
    Case("capture-read-written-twice", "a read written twice: decoded twice, as a reset",
         _read_written_twice, (0,), "1 sample(s) repeat an earlier one exactly"),
    # 3. inputs bounded
    Case("export-deep-json", "a result of [ x 100000: RecursionError in export",
         lambda d: ["export", str(_deep(d, "Q1_result.json")), "--to", "px4"], (2,),
         "JSON nested 100000 deep"),
    Case("archive-add-deep-json", "a result of [ x 100000: RecursionError in archive add",
         _archive_add_deep, (2,), "JSON nested 100000 deep"),
    Case("export-thermal-deep-json", "a thermal file of [ x 100000: RecursionError",
         lambda d: ["export", str(_calibrated(d)), "--to", "px4", "--allow-fail", "--thermal",
                    str(_deep(d))], (2,), "JSON nested 100000 deep"),
    Case("calibrate-noise-deep-json", "a noise file of [ x 100000: RecursionError",
         lambda d: ["calibrate", "--from-dir", str(_session(d)), "--noise", str(_deep(d)),
                    "--no-archive"], (2,), "JSON nested 100000 deep"),
    Case("kalibr-noise-deep-json", "a noise file of [ x 100000 for Kalibr",
         lambda d: ["export", "--to", "kalibr", "--noise", str(_deep(d))], (2,),
         "JSON nested 100000 deep"),
    Case("record-times-all-equal", "a record whose time stamps are all equal: accepted",
         lambda d: _edited(d, lambda t: _times(t, lambda v: "100.0")), (2,),
         "every time stamp is 100 ms"),
    Case("record-times-in-seconds", "a record's times in seconds, not ms: accepted",
         lambda d: _edited(d, lambda t: _times(t, lambda v: f"{v / 1000:.4f}")), (2,),
         "they look like seconds"),
    Case("record-two-serials", "two different '# serial:' headers in one record: accepted",
         lambda d: _edited(d, lambda t: "# serial: Q2\n" + t), (2,),
         "a second 'serial:' header line ('Q1') contradicts the first ('Q2')"),
    Case("record-power-on-inf", "# power_on_s: inf: a numpy warning, then a term blamed",
         lambda d: _edited(d, lambda t: re.sub(r"# power_on_s: .*", "# power_on_s: inf", t)),
         (2,), "header 'power_on_s: inf' is not a finite number"),
    # 4. nothing replaced silently
    Case("from-dir-beside-a-live-session", "--from-dir ignores a live session's lock",
         lambda d: ["calibrate", "--from-dir", str(_locked(_session(d))), "--no-archive"],
         (2,), "is in use by another process"),
    Case("from-dir-into-a-busy-out", "two --from-dir into one --out: both succeed, one wins",
         lambda d: ["calibrate", "--from-dir", str(_session(d)), "--out",
                    str(_locked(d / "out")), "--no-archive"], (2,),
         "is in use by another process"),
    Case("from-dir-over-other-records", "a result of other records replaced, no earlier/ copy",
         _earlier_result_of_other_records, (0, 1), "of other records, moved to"),
    # 6. a closed pipe ends a command quietly
    Case("terms-into-a-closed-pipe", "model terms | head -0: 'error: broken pipe', exit 2",
         lambda d: ["model", "terms"], (0,), process=True, head_lines=0),
    Case("export-into-a-closed-pipe", "export RESULT | head -0: 'error: broken pipe'",
         lambda d: ["export", str(_calibrated(d)), "--to", "px4", "--allow-fail"], (0,),
         process=True, head_lines=0),
    # 6. every command reads what another wrote
    Case("noise-of-a-record-without-header", "noise refuses a record calibrate reads",
         _noise_of_a_bare_record, (0,), out_words="record z_up"),
    Case("thermal-of-a-session-with-warmup", "thermal refuses a dialogue's session with its "
         "warm-up: 'each attitude was measured at a single temperature'",
         _session_with_warmup, (0,), "written:"),
    # 5. a term file's process ending is a failure
    Case("term-os-exit-0", "a term calling os._exit(0): exit 0, no result",
         lambda d: _term_ends(d, "os._exit(0)"), (2,), "called os._exit(0)", process=True),
    Case("term-file-os-exit-0", "a term file calling os._exit(0) as it loads",
         lambda d: _term_ends(d, "os._exit(0)", at_load=True), (2,), "loading it called os._exit",
         process=True),
    Case("term-sys-exit-0", "a term calling sys.exit(0)",
         lambda d: _term_ends(d, "import sys; sys.exit(0)"), (2,), "called sys.exit(0)",
         process=True),
)  # fmt: skip
