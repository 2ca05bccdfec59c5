"""``python3 -m host archive``: every calibration kept by serial, and the questions of a lab
and a production line (:mod:`host.archive`). Thin: parse, call the library, print."""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from host.archive import checks, stats
from host.archive.entry import entry_from_directory
from host.archive.export import COLUMNS, EARLIER_COLUMNS, write_values
from host.archive.store import Archive
from host.cli import archive_text as text
from host.cli.options import Command, add_archive_option, positive
from host.cli.screen import terminal_width
from host.errors import UserError, write_error


def _alpha(s: str) -> float:
    try:
        v = float(s)
    except ValueError:
        v = math.nan
    if not 0 < v < 1:
        raise argparse.ArgumentTypeError(f"expected a rate between 0 and 1, got {s!r}")
    return v


def parse_tolerances(items: list[str]) -> dict[str, float]:
    """``--tol A0x=0.02 --tol G0z=0.1`` (or comma-separated) -> {name: tolerance}."""
    out: dict[str, float] = {}
    for item in ",".join(items).split(","):
        if not item.strip():
            continue
        name, _, val = item.partition("=")
        try:
            v = float(val)
        except ValueError:
            v = math.nan
        if not name.strip() or not v > 0:
            raise UserError(f"--tol: expected NAME=VALUE (> 0), got {item!r}")
        out[name.strip()] = v
    return out


@dataclass(frozen=True)
class ArchiveOptions:
    """``archive ACTION``: the action, the archive (None: the default one), which
    calibrations (serial, bench, lot; ``param``: which parameters, None: all), the
    false-alarm rate, and what the actions of their own take: the directories ``add`` reads
    (their records', who measured), the id ``show`` shows, the pooling of ``repeat``, the
    k·σ and tolerances of ``drift``, the reference unit, the page and the file written."""

    action: str
    archive: str | None = None
    serial: str | None = None
    bench: str | None = None
    lot: str | None = None
    param: tuple[str, ...] | None = None
    alpha: float = stats.DEFAULT_ALPHA
    dirs: tuple[str, ...] = ()
    records: str | None = None
    operator: str | None = None
    id: int | None = None
    across_benches: bool = False
    k: float | None = None
    tol: tuple[str, ...] = ()
    reference: str | None = None
    html: str = ""
    file: str = ""


#: what an action the namespace lacks an argument of takes (every action reads its own only)
_UNSET = {"serial": None, "bench": None, "lot": None, "param": None,
          "alpha": stats.DEFAULT_ALPHA, "dirs": (), "records": None, "operator": None,
          "id": None, "across_benches": False, "k": None, "tol": (), "reference": None,
          "html": "", "file": ""}  # fmt: skip


def archive_options(ns: argparse.Namespace) -> ArchiveOptions:
    """The ``archive`` options from its arguments (the action's, the rest unset)."""
    given = vars(ns)
    v: dict[str, Any] = {name: given.get(name, unset) for name, unset in _UNSET.items()}
    return ArchiveOptions(
        action=ns.archive_command, archive=ns.archive, serial=v["serial"], bench=v["bench"],
        lot=v["lot"], param=None if v["param"] is None else tuple(v["param"]),
        alpha=v["alpha"], dirs=tuple(v["dirs"]), records=v["records"],
        operator=v["operator"], id=v["id"], across_benches=v["across_benches"], k=v["k"],
        tol=tuple(v["tol"]), reference=v["reference"], html=v["html"], file=v["file"],
    )  # fmt: skip


def _open(args: ArchiveOptions, create: bool = False) -> Archive:
    """The archive of ``--archive``; only ``add`` creates one (a question to an archive that
    is not there, a typo in its path, is not answered from a new empty one)."""
    return Archive(args.archive, create=create)


def _add(args: ArchiveOptions) -> int:
    with _open(args, create=True) as a:
        for d in args.dirs:
            e = entry_from_directory(
                d, serial=args.serial, records_dir=args.records, bench=args.bench,
                operator=args.operator, lot=args.lot,
            )  # fmt: skip
            cid, added = a.add(e)
            what = "archived" if added else "already archived"
            said = (f"{what}: #{cid} {e.serial} {e.measured_at[:19]} {e.verdict.upper()} "
                    f"result {e.result_hash[:12]} in {a.display_url}")  # fmt: skip
            print("\n".join(text.prose(said, terminal_width())))
    return 0


def _list(args: ArchiveOptions) -> int:
    with _open(args) as a:
        sys.stdout.write(text.summaries(a.summaries(args.serial, args.bench, args.lot)))
    return 0


def _show(args: ArchiveOptions) -> int:
    with _open(args) as a:
        if args.id is not None:
            key: int | str = args.id
        else:
            rows = a.summaries(serial=args.serial)
            if not rows:
                raise UserError(f"{args.serial}: no calibration of this serial in the archive")
            sys.stdout.write(text.summaries(rows) + "\n")
            key = rows[-1].id
        sys.stdout.write(text.entry(a.entry(key)))
    return 0


def _trend(args: ArchiveOptions) -> int:
    serial = args.serial or ""  # (its parser requires it)
    with _open(args) as a:
        sys.stdout.write(text.trend(serial, checks.trend(a, serial, args.param)))
    return 0


def _selected(
    a: Archive,
    serial: str | None,
    lot: str | None,
    names: Sequence[str] | None = None,
    option: str = "--param",
) -> None:
    """A UserError when no calibration is of ``serial`` in ``lot`` — or none at all — or a
    parameter of ``names`` (given with ``option``) is in none of them: a check of a unit, a
    lot or a parameter that is not there must not read as one that passed."""
    if not a.summaries(serial, None, lot):
        sel = [f"of {serial}" if serial else "", f"in lot {lot}" if lot else ""]
        raise checks.nothing_selected(a, " ".join(w for w in sel if w), None)
    if names:
        found = set(a.values(list(names), serial=serial, lot=lot).name.tolist())
        unknown = [n for n in names if n not in found]
        if unknown:
            known = sorted(set(a.values(serial=serial, lot=lot).name.tolist()))
            raise UserError(
                f"{option} {', '.join(unknown)}: no such parameter in these calibrations "
                f"(they have {', '.join(known)})"
            )


def _repeat(args: ArchiveOptions) -> int:
    with _open(args) as a:
        _selected(a, args.serial, args.lot)
        pooled, lot = args.across_benches, args.lot
        rows = checks.repeat(a, args.serial, alpha=args.alpha, across_benches=pooled, lot=lot)
        same = checks.identical_repeats(a, args.serial, across_benches=pooled, lot=lot)
    sys.stdout.write(text.repeat(rows, args.alpha, identical=same))
    return 1 if same or any(r.failed for r in rows) else 0


def _left_out(n: int) -> str:
    """The line that says how many simulated calibrations the statistics left out ('')."""
    if not n:
        return ""
    return (f"left out of these statistics: {n} simulated calibration(s) (sim://, emu://: "
            "not a unit; archive list shows them)\n")  # fmt: skip


def _drift(args: ArchiveOptions) -> int:
    tol = parse_tolerances(list(args.tol))
    with _open(args) as a:
        _selected(a, args.serial, args.lot, list(tol), "--tol")  # a parameter not there
        rows, k = checks.drift(
            a, alpha=args.alpha, k=args.k, tolerances=tol, serial=args.serial, lot=args.lot
        )
        left = a.simulated_count(serial=args.serial, lot=args.lot)
    sys.stdout.write(text.drift(rows, k, args.alpha) + _left_out(left))
    return 1 if any(r.moved for r in rows) else 0


def _lot(args: ArchiveOptions) -> int:
    with _open(args) as a:
        rep = checks.lot_report(a, args.lot, alpha=args.alpha, names=args.param)
        if not rep.units:  # a lot that is not there is not a lot that passed
            lot = f"in lot {args.lot}" if args.lot else "with these parameters"
            raise checks.nothing_selected(a, lot, args.param)
        left = a.simulated_count(lot=args.lot)
    sys.stdout.write(text.lot(rep, args.alpha) + _left_out(left))
    odd = any(r.outliers or r.summary.within is False for r in rep.rows)
    bad = bool(rep.failing or rep.conditional) or odd
    return 1 if bad else 0


def _control(args: ArchiveOptions) -> int:
    with _open(args) as a:
        cs = checks.control_charts(a, serial=args.serial, bench=args.bench, names=args.param)
        if not cs:
            sel = [f"of {args.serial}" if args.serial else "", f"on {args.bench}" if args.bench
                   else ""]  # fmt: skip
            raise checks.nothing_selected(a, " ".join(w for w in sel if w), args.param)
        left = a.simulated_count(serial=args.serial, bench=args.bench)
    sys.stdout.write(text.charts(cs) + _left_out(left))
    return 0


def _check_bench(args: ArchiveOptions) -> int:
    reference = args.reference or ""  # (its parser requires it)
    with _open(args) as a:
        rows, k = checks.check_bench(a, reference, alpha=args.alpha)
    sys.stdout.write(text.benches(rows, k, args.alpha, reference))
    return 1 if any(r.flagged for r in rows) else 0


def _only_an_earlier_export(path: Path) -> None:
    """UserError when ``path`` holds a file that is not an earlier ``archive export`` (its
    CSV header, or Parquet's magic): a user's own table is kept, not replaced (it was)."""
    if not path.is_file():
        return
    with path.open("rb") as f:
        head = f.read(64)
    ours = [b"PAR1"] if path.suffix.lower() in (".parquet", ".pq") else [
        ",".join(cols).encode()[:64] for cols in (COLUMNS, EARLIER_COLUMNS)
    ]  # fmt: skip
    if not any(head.startswith(o) for o in ours):
        raise UserError(
            f"{path}: exists and is no export of the archive; it is kept: give another file "
            "name, or move it away first"
        )


def _export(args: ArchiveOptions) -> int:
    if Path(args.file).is_dir():
        raise UserError(
            f"{args.file}: is a directory; give a file name, e.g. {Path(args.file) / 'values.csv'}"
        )
    if Path(args.file).suffix.lower() not in (".csv", ".parquet", ".pq"):
        raise UserError(f"{args.file}: write .csv or .parquet")  # before asking the archive
    _only_an_earlier_export(Path(args.file))
    with _open(args) as a:
        _selected(a, args.serial, args.lot, args.param)  # never an empty file, exit 0
        lots = {s.id: s.lot for s in a.summaries(args.serial, None, args.lot)}
        n = write_values(a.values(args.param, serial=args.serial, lot=args.lot), args.file, lots)
    print(f"written: {args.file} ({n} rows)", file=sys.stderr)
    return 0


#: the page's name in a directory given to ``archive report --html``
PAGE_NAME = "qc.html"


def page_path(html: str) -> Path:
    """Where ``archive report --html HTML`` writes: the file HTML, or ``HTML/qc.html`` when
    HTML is a directory — one that exists, or one written with a trailing ``/`` (made here;
    its parent must exist). An empty name is a UserError naming what to give."""
    if not html.strip():
        raise UserError(f"--html '': give the page's file name, e.g. --html {PAGE_NAME}")
    path = Path(html).expanduser()
    if html.endswith(("/", os.sep)) and not path.exists():
        try:
            path.mkdir()
        except OSError as exc:
            raise write_error(path, exc, "nothing was written") from None
    return path / PAGE_NAME if path.is_dir() else path


def _report(args: ArchiveOptions) -> int:
    from host.archive.page import page_data, render
    from host.session.atomic import write_text_atomic

    with _open(args) as a:
        _selected(a, None, args.lot, args.param)  # a lot or parameter that is not there
        d = page_data(a, reference=args.reference, lot=args.lot, names=args.param,
                      alpha=args.alpha)  # fmt: skip
    path = page_path(args.html)
    write_text_atomic(path, render(d))
    print(f"written: {path}", file=sys.stderr)
    return 0


#: each action's examples (what follows ``python3 -m host archive ACTION``)
ARCHIVE_EXAMPLES: dict[str, tuple[str, ...]] = {
    "add": (" U17/\n      keep U17's result", " runs/*/ --bench B2 --lot L7"),
    "list": ("", " --serial U17"),
    "show": (" U17", " --id 12"),
    "trend": (" U17 --param G0x",),
    "repeat": (" U17\n      do its calibrations agree within σ?", " --across-benches"),
    "drift": ("\n      which units moved: recalibrate", " --tol G0x=0.05"),
    "lot": (" L7", " --param Gxx"),
    "control": (" --serial REF01",),
    "check-bench": (" REF01",),
    "report": (" --html qc.html --reference REF01",),
    "export": (" values.csv --lot L7",),
}


def cli_archive(p: argparse.ArgumentParser) -> Command[ArchiveOptions]:
    """Fill in the ``archive`` subparser; returns the command."""
    common = argparse.ArgumentParser(add_help=False)
    add_archive_option(common, "the archive")
    alpha = argparse.ArgumentParser(add_help=False)
    alpha.add_argument(
        "--alpha", type=_alpha, default=stats.DEFAULT_ALPHA,
        help="false-alarm rate of one run over a lot with nothing wrong (default 0.01)",
    )  # fmt: skip
    sub = p.add_subparsers(dest="archive_command", metavar="ACTION", required=True)

    def action(name: str, help_text: str, *parents: argparse.ArgumentParser) -> Parser:
        return sub.add_parser(
            name, help=help_text, description=help_text, parents=[common, *parents],
            epilog="examples:\n" + "\n".join(f"  python3 -m host archive {name}{e}"
                                              for e in ARCHIVE_EXAMPLES[name]),
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )  # fmt: skip

    _keeping_actions(action)
    _question_actions(action, alpha)
    _page_actions(action, alpha)
    return Command(archive_options, run)


#: a function adding one action's subparser: (name, help, parent parsers) -> its parser
Parser = argparse.ArgumentParser
Action = Callable[..., Parser]
SERIAL_HELP = "only this unit's calibrations"
BENCH_HELP = "only the calibrations on this bench"
LOT_HELP = "only the calibrations of this production lot"
PARAM_HELP = "only this parameter (repeatable; default: every one)"


def _keeping_actions(action: Action) -> None:
    """add, list, show, trend: what is kept."""
    q = action("add", "archive the results calibrate wrote (same result twice: no-op)")
    q.add_argument("dirs", nargs="+", metavar="DIR", help="directory of SERIAL_result.json")
    q.add_argument("--serial", help="which result, when DIR holds several")
    q.add_argument("--records", metavar="DIR", help="the records' directory (default DIR)")
    q.add_argument("--bench", help="bench name (default: the records' header, $IMU_BENCH_NAME)")
    q.add_argument("--operator", help="operator (default: the records', $IMU_BENCH_OPERATOR)")
    q.add_argument("--lot", help="production lot (default: the records' header)")
    q = action("list", "list archived calibrations")
    q.add_argument("--serial", help=SERIAL_HELP)
    q.add_argument("--bench", help=BENCH_HELP)
    q.add_argument("--lot", help=LOT_HELP)
    q = action("show", "a unit's calibrations and the latest (or --id) in full")
    q.add_argument("serial", nargs="?", help="the unit whose calibrations to list")
    q.add_argument("--id", type=int, help="show this calibration (an id from 'archive list')")
    q = action("trend", "each parameter of a unit against time, with its σ")
    q.add_argument("serial", help="the unit")
    q.add_argument("--param", action="append", metavar="NAME", help="only these parameters")


def _question_actions(action: Action, alpha: Parser) -> None:
    """repeat, drift, lot, control: a lab's and a line's questions."""
    q = action("repeat", "between-session scatter against the predicted σ; copies named", alpha)
    q.add_argument("serial", nargs="?", help="one unit (default: every unit)")
    q.add_argument("--lot", help=LOT_HELP)
    q.add_argument("--across-benches", action="store_true",
                   help="pool a unit's sessions on all benches (reproducibility)")  # fmt: skip
    q = action("drift", "units that moved since their last calibration", alpha)
    q.add_argument("--k", type=positive, help="flag beyond k·σ (default: from --alpha)")
    q.add_argument("--tol", action="append", default=[], metavar="NAME=VALUE",
                   help="flag a change beyond this, in the parameter's unit")  # fmt: skip
    q.add_argument("--serial", help=SERIAL_HELP)
    q.add_argument("--lot", help=LOT_HELP)
    q = action("lot", "per parameter: mean, spread, 3σ vs the datasheet, outliers", alpha)
    q.add_argument("lot", nargs="?", help="the lot (default: every unit)")
    q.add_argument("--param", action="append", metavar="NAME", help=PARAM_HELP)
    q = action("control", "control charts per bench and parameter, run rules")
    q.add_argument("--serial", help="chart this unit only (e.g. the reference unit)")
    q.add_argument("--bench", help=BENCH_HELP)
    q.add_argument("--param", action="append", metavar="NAME", help=PARAM_HELP)


def _page_actions(action: Action, alpha: Parser) -> None:
    """check-bench, report, export: the benches compared, the QC page, the values."""
    q = action("check-bench", "compare benches on a reference unit (Eₙ)", alpha)
    q.add_argument("reference", help="serial of the reference unit calibrated on every bench")
    q = action("report", "one self-contained HTML page for the QC lead", alpha)
    q.add_argument("--html", required=True, metavar="FILE",
                   help=f"the page to write (a directory: {PAGE_NAME} in it)")  # fmt: skip
    q.add_argument("--reference", metavar="SERIAL", help="the reference unit (bench check)")
    q.add_argument("--lot", help=LOT_HELP)
    q.add_argument("--param", action="append", metavar="NAME", help="parameters to chart")
    q = action("export", "values as CSV (or Parquet with pyarrow)")
    q.add_argument("file", help="FILE.csv or FILE.parquet")
    q.add_argument("--serial", help=SERIAL_HELP)
    q.add_argument("--lot", help=LOT_HELP)
    q.add_argument("--param", action="append", metavar="NAME", help=PARAM_HELP)


#: each action's runner
ACTIONS: dict[str, Callable[[ArchiveOptions], int]] = {
    "add": _add, "list": _list, "show": _show, "trend": _trend, "repeat": _repeat,
    "drift": _drift, "lot": _lot, "control": _control, "check-bench": _check_bench,
    "report": _report, "export": _export,
}  # fmt: skip


def run(args: ArchiveOptions) -> int:
    """Runner of ``python3 -m host archive``: the action's."""
    return ACTIONS[args.action](args)
