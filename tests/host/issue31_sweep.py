"""The bad inputs of issue 31's second sweep, on the commands of the last waves: ``plan DIR``
and ``--separate A B``, ``calibrate --plan adaptive`` with ``--target`` and ``--max-extra``,
``archive`` with database URLs of every form and ``report --html``, ``model add|diagnose|
ladder`` with odd term files, ``export`` to odd places, ``import`` with odd labels files, and
the resume/redo command of an error under a long ``--out``. The cases are
:class:`tests.host.issue17_sweep.Case`: ``tests/host/test_issue17_sweep.py`` runs them on every
CI run and ``python3 -m tests.host.issue17_sweep`` as real processes, with issue 17's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tests.host.issue17_sweep import Case, _session, _term

#: a directory name long enough that a command naming it cannot fit 80 columns
LONG = "a directory name long enough to pass eighty columns, with spaces"


def _calibrated(d: Path) -> Path:
    """A session with its result files (what ``calibrate --from-dir`` writes)."""
    from host.calib.publish import ComputeSettings, compute_and_write
    from host.session.directory import read_session

    s = _session(d)
    compute_and_write(read_session(s, None), s, ComputeSettings())
    return s


def _archived(d: Path) -> str:
    """An archive holding one calibration; its path."""
    from host.archive.store import archive_directory

    db = str(d / "a.sqlite")
    archive_directory(_calibrated(d), db)
    return db


# --------------------------------------------------------------------------- resume and redo


def _redo_under_a_long_out(d: Path) -> list[str]:
    from host.bench.plan import Plan, simulate_session, write_session
    from host.bench.truth import SensorTruth

    recs = simulate_session(SensorTruth.ideal(), Plan(static_s=2.0, turns=1), seed=4)
    bad = recs["y_ccw"]
    recs["y_ccw"] = type(bad)(bad.name, bad.t_ms, bad.accel, bad.gyro * 0.8, bad.temp, bad.meta)
    out = d / LONG / "R1"
    write_session(out, "R1", recs)
    return ["calibrate", "--from-dir", str(out)]


# --------------------------------------------------------------------------- archive


def _report_into_a_directory(d: Path) -> list[str]:
    db = _archived(d)
    (d / "pages").mkdir()
    return ["archive", "report", "--html", str(d / "pages"), "--archive", db]


def _drift_tol_not_there(d: Path) -> list[str]:
    return ["archive", "drift", "--tol", "G0q=0.1", "--archive", _archived(d)]


def _report_lot_not_there(d: Path) -> list[str]:
    return ["archive", "report", "--html", str(d / "p.html"), "--lot", "L9", "--archive",
            _archived(d)]  # fmt: skip


def _result_serial_a_path(d: Path) -> list[str]:
    import json

    s = _calibrated(d)
    doc = json.loads((s / "Q1_result.json").read_text())
    (s / "Q1_result.json").write_text(json.dumps({**doc, "serial": "../../etc"}))
    return ["archive", "add", str(s), "--archive", str(d / "a.sqlite")]


def _archive_export_over_a_table(d: Path) -> list[str]:
    (d / "mine.csv").write_text("lot,unit,my notes\nL7,U1,fine\n")
    return ["archive", "export", str(d / "mine.csv"), "--archive", _archived(d)]


# --------------------------------------------------------------------------- term files


def _undetermined_term(d: Path) -> list[str]:
    f = _term(d, "flat", "return np.zeros(len(sig.t_s))")
    return ["model", "add", str(_session(d)), "flat:gyro", "--term-file", str(f)]


def _ladder_term_raises(d: Path) -> list[str]:
    f = _term(d, "wob", "raise ValueError('my ladder bug')")
    return ["model", "ladder", str(_session(d)), "--term-file", str(f)]


# --------------------------------------------------------------------------- export


def _export_over_a_vehicle_file(d: Path) -> list[str]:
    (d / "vehicle.parm").write_text("SERIAL0_BAUD 115\nINS_ACCOFFS_X 0.1\n")
    return ["export", str(_calibrated(d)), "--to", "ardupilot", "--allow-fail", "--out",
            str(d / "vehicle.parm")]  # fmt: skip


def _export_into_a_directory(d: Path) -> list[str]:
    return ["export", str(_calibrated(d)), "--to", "px4", "--allow-fail", "--out", str(d)]


# --------------------------------------------------------------------------- import --labels


def _stream_csv(d: Path) -> Path:
    """40 s at 50 Hz: x up still 10 s, two turns ccw about x in 10 s, still 10 s, y up 10 s."""
    t = np.arange(2000) / 50.0
    accel = np.zeros((2000, 3))
    accel[:1500, 0] = 9.81
    accel[1500:, 1] = 9.81
    gyro = np.zeros((2000, 3))
    gyro[500:1000, 0] = 72.0  # °/s: 720° in 10 s
    rng = np.random.default_rng(3)
    accel += rng.normal(0, 0.01, accel.shape)
    gyro += rng.normal(0, 0.02, gyro.shape)
    p = d / "log.csv"
    rows = np.column_stack([t, accel, gyro])
    p.write_text("".join(",".join(f"{v:.6f}" for v in r) + "\n" for r in rows))
    return p


def _import_with(d: Path, *rows: str, bom: bool = False) -> list[str]:
    labels = d / "l.tsv"
    text = ("# imu-bench segments v2 of log.csv\n"
            "# row\tstart_s\tend_s\tlabel\theading_deg\tfound\tquality\treason\n"
            + "".join(f"{i}\t{r}\t-\t-\t-\t-\n" for i, r in enumerate(rows, start=1)))  # fmt: skip
    labels.write_bytes(("\ufeff" if bom else "").encode() + text.encode())
    return ["import", str(_stream_csv(d)), "--columns", "t,ax,ay,az,gx,gy,gz", "--serial",
            "L1", "--out", str(d / "L1"), "--labels", str(labels)]  # fmt: skip


_ADAPTIVE = ["calibrate", "--serial", "A1", "--yes", "--warmup", "0", "--static-seconds", "2",
             "--no-archive"]  # fmt: skip

CASES: tuple[Case, ...] = (
    Case("redo-under-a-long-out", "a redo command of 200 columns under a long --out",
         _redo_under_a_long_out, (2,), "measure y_ccw again", width=True),
    Case("archive-report-into-a-dir", "report --html DIR said 'permission denied'",
         _report_into_a_directory, (0,), "pages/qc.html"),
    Case("archive-url-bad-port", "a URL whose port is no number: ValueError traceback",
         lambda d: ["archive", "list", "--archive", "postgresql://qc@db:5432x/line"], (2,),
         "not a database URL"),
    Case("archive-url-open-bracket", "a URL with a [ not closed: ValueError traceback",
         lambda d: ["archive", "list", "--archive", "postgresql://qc:pw@[::1/line"], (2,),
         "postgresql://qc:***@[::1/line: not a database URL"),
    Case("archive-url-empty", "--archive '' fell back to the default archive",
         lambda d: ["archive", "list", "--archive", ""], (2,), "--archive '': an empty value"),
    Case("archive-url-unreachable", "a server nobody answers on",
         lambda d: ["archive", "list", "--archive", "postgresql://qc@127.0.0.1:1/line"], (2,),
         "cannot open it"),
    Case("archive-path-typo", "drift on a path with a typo made an archive: 'no unit moved'",
         lambda d: ["archive", "drift", "--archive", str(d / "typo.sqlite")], (2,),
         "no such file; 'archive add DIR' or calibrate creates it"),
    Case("archive-path-is-a-dir", "a directory as the archive: 'unable to open database file'",
         lambda d: ["archive", "list", "--archive", str(d)], (2,), "is a directory"),
    Case("archive-tol-not-there", "drift --tol of a parameter not archived: ignored, exit 0",
         _drift_tol_not_there, (2,), "--tol G0q: no such parameter"),
    Case("archive-report-lot-not-there", "report of a lot not archived: a page, exit 0",
         _report_lot_not_there, (2,), "no calibration in lot L9"),
    Case("archive-bench-escape", "--bench with an escape sequence: kept in the archive",
         lambda d: ["archive", "add", str(_calibrated(d)), "--bench", "b\x1b[2J", "--archive",
                    str(d / "a.sqlite")], (2,), "--bench: 'b\\x1b[2J' holds a control"),
    Case("calibrate-lot-line-break", "--lot with a line break: every record's header",
         lambda d: ["calibrate", "--port", "sim://", "--serial", "S1", "--yes",
                    "--static-seconds", "1", "--out", str(d / "o"), "--lot", "L\n7"], (2,),
         "--lot: 'L\\n7' holds a control character"),
    Case("archive-result-serial-a-path", "a result whose serial is a path: ValueError",
         _result_serial_a_path, (2,), "not a result this program wrote (its serial"),
    Case("plan-json", "plan --json on a whole session", lambda d: ["plan", str(_session(d)),
         "--json", "--top", "2"], (0,), out_words='"ranked"'),
    Case("plan-separate-same", "--separate A A ranked records that separate by 0",
         lambda d: ["plan", str(_session(d)), "--separate", "scale_asymmetry:gyro:z",
                    "scale_asymmetry:gyro:z"], (2,), "the same explanation twice"),
    Case("plan-separate-in-model", "--separate with a term the model has",
         lambda d: ["plan", str(_session(d)), "--separate", "bias:gyro", "time_drift:gyro"],
         (2,), "--separate bias:gyro: already in the model"),
    Case("plan-place-1e300", "--place-s 1e300 filled the table with digits",
         lambda d: ["plan", str(d), "--place-s", "1e300"], (2,), "give 0 to 3600 seconds"),
    Case("redo-nothing", "--redo ',' began a whole new sitting (the earlier moved aside)",
         lambda d: [*_ADAPTIVE, "--out", str(_session(d)), "--redo", ","], (2,),
         "--redo ',': give the record names"),
    Case("adaptive-target-without-plan", "--target without --plan adaptive: ignored",
         lambda d: [*_ADAPTIVE, "--out", str(d / "A1"), "--target", "0.01"], (2,),
         "only --plan adaptive reads it"),
    Case("adaptive-max-extra-million", "--max-extra 1000000 ran on with no end in sight",
         lambda d: [*_ADAPTIVE, "--out", str(d / "A1"), "--plan", "adaptive", "--max-extra",
                    "1000000"], (2,), "give 0 to 60 records"),
    Case("adaptive-from-dir", "--plan adaptive with --from-dir: recomputed as fixed",
         lambda d: ["calibrate", "--from-dir", str(_session(d)), "--plan", "adaptive",
                    "--no-archive"], (2,), "--plan adaptive is for a live calibration"),
    Case("term-values-1e300", "a term of 1e300: LinAlgError 'SVD did not converge' traceback",
         lambda d: ["model", "add", str(_session(d)), "big:gyro", "--term-file",
                    str(_term(d, "big", "return np.full(len(sig.t_s), 1e300)"))], (2,),
         "beyond the fit's range"),
    Case("term-complex", "complex columns: their real part taken, exit 0",
         lambda d: ["model", "diagnose", str(_session(d)), "--term-file",
                    str(_term(d, "cx", "return sig.t_s * 1j"))], (2,),
         "returned complex numbers"),
    Case("term-undetermined", "a zero column: '— ± —' and 'ship this model'",
         _undetermined_term, (0,), out_words="not shipped: these records do not determine"),
    Case("term-file-is-a-dir", "a directory as the term file: 'no such term file'",
         lambda d: ["model", "diagnose", str(_session(d)), "--term-file", str(d)], (2,),
         "is a directory; give the Python file"),
    Case("ladder-term-raises", "a ladder over a term file whose term raises",
         _ladder_term_raises, (2,), "raised ValueError: my ladder bug"),
    Case("export-over-a-vehicle-file", "--out over another file replaced it, silently",
         _export_over_a_vehicle_file, (2,), "it is kept"),
    Case("export-into-a-dir", "--out DIR said 'permission denied'",
         _export_into_a_directory, (2,), "is a directory; give a file name"),
    Case("export-a-record", "a record given as the result: 'calibration result: not valid JSON'",
         lambda d: ["export", str(_session(d) / "Q1_x_up.txt"), "--to", "px4"], (2,),
         "Q1_x_up.txt: calibration result: not valid JSON"),
    Case("export-thermal-not-there", "--thermal FILE not there: '[Errno 2] No such file …'",
         lambda d: ["export", str(_calibrated(d)), "--to", "px4", "--allow-fail", "--thermal",
                    str(d / "T_thermal.json")], (2,), "T_thermal.json: no such file (python3"),
    Case("export-axes-empty", "--axes '' exported in our axes",
         lambda d: ["export", str(d), "--to", "px4", "--axes", ""], (2,), "--axes '': an empty"),
    Case("export-axes-minus", "--axes -x,-y,z: 'expected one argument', no way out",
         lambda d: ["export", str(d), "--to", "px4", "--axes", "-x,-y,z"], (2,),
         "goes as --axes=VALUE"),
    Case("labels-past-the-stream", "a row to 1e9 s: the whole stream one static record",
         lambda d: _import_with(d, "0\t1e9\tx_up"), (2,), "reaches past the stream"),
    Case("labels-wrong-face", "y_up where gravity is along x: a record of the wrong face",
         lambda d: _import_with(d, "1\t9\ty_up"), (2,), "gravity is along x_up"),
    Case("labels-rest-as-turn", "a rest labelled x_ccw: a turn record of no turn, exit 0",
         lambda d: _import_with(d, "1\t9\tx_ccw"), (2,), "no turn"),
    Case("labels-overlap", "two statics on one sample: records sharing samples, exit 0",
         lambda d: _import_with(d, "1\t9\tx_up", "5\t9.5\tx_up_2"), (2,), "overlap"),
    Case("labels-bom", "a byte-order mark hid the first row's numbers",
         lambda d: _import_with(d, "1\t9\tx_up", "9\t21\tx_ccw", "31\t39\ty_up", bom=True),
         (0,)),
    Case("empty-out", "--out '' (an unset variable): the records written into the current dir",
         lambda d: ["import", str(_stream_csv(d)), "--columns", "t,ax,ay,az,gx,gy,gz",
                    "--serial", "L1", "--out", ""], (2,), "--out '': an empty value"),
    Case("empty-dir", "plan '' read the current directory's records",
         lambda d: ["plan", ""], (2,), "'': an empty argument"),
    Case("archive-export-over-a-table", "archive export over the user's own CSV: replaced",
         _archive_export_over_a_table, (2,), "exists and is no export of the archive"),
    Case("import-out-a-file", "import --out FILE: '[Errno 17] File exists'",
         lambda d: [*_import_with(d, "1\t9\tx_up")[:-4], "--out", str(_stream_csv(d))], (2,),
         "is a file; give a directory"),
    Case("plot-where-none-can-be", "--plot under /proc: '[Errno 2] No such file or directory'",
         lambda d: ["model", "add", str(_session(d)), "temperature_bias:gyro", "--plot",
                    "/proc/no/plots"], (2,), ": no such file or directory; check the path"),
    Case("labels-and-record", "--record beside --labels left the labels unused",
         lambda d: [*_import_with(d, "1\t9\tx_up"), "--record", "x_up"], (2,),
         "--record and --labels: give one"),
)  # fmt: skip
