"""``python3 -m host noise FILE``: Allan deviation of a static recording, its noise figures,
a recording planner, and the noise file the workbench takes its noise floor from.

FILE is a capture (``.cap`` IMUCAP01 or raw bytes, as ``capture`` writes them; streamed, in
bounded memory at any length: :mod:`host.cli.noise_source`) or a record file
(``SERIAL_name.txt``, from the dialogue or from ``import``). The math is in
:mod:`host.model.recording` and :mod:`host.model.allan`.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from host.cli import pyplot
from host.cli.figures import DPI, noise_figure
from host.cli.options import Command
from host.cli.screen import Column, table, terminal_width
from host.errors import UserError
from host.model import allan, recording
from host.session.atomic import write_text_atomic
from host.session.records import Record, RecordError
from host.session.spacing import quality_report, timing_report


def load_record(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """Times (N,) s, channels (N, 6) ax..gz in m/s² and °/s, temperature (N,) °C of a static
    record file, and a one-line description of what was read."""
    from host.session.directory import read_record

    give = "give a static record (SERIAL_x_up.txt) or a capture of the unit at rest (.cap)"
    with open(path, "rb") as fh:
        head = fh.read(64)
    if head.startswith(b"TEST REPORT"):
        raise UserError(f"{path}: the calibration report, not a recording; {give}")
    try:  # with its header or without, as calibrate --from-dir reads it (method.md §6)
        rec = read_record(path)
    except RecordError as exc:
        raise UserError(f"{exc} — not a record, nor a recording; {give}") from None
    if rec.kind == "turn":
        raise UserError(
            f"{path}: a turn record (the cube turned by hand), not a recording at rest; give "
            "a static record (SERIAL_x_up.txt) or a capture of the unit at rest (.cap)"
        )
    data = np.column_stack([rec.accel, rec.gyro])
    return rec.t_ms / 1000.0, data, rec.temp, f"record {rec.name} ({len(rec)} samples)"


def analyse_file(
    path: Path, remove_thermal: bool, ci: float
) -> tuple[recording.NoiseAnalysis, str]:
    """The noise of a static record file (read whole) or capture (streamed: bounded memory at
    any length, :mod:`host.cli.noise_source`), its timing table on stderr when irregular; and
    a one-line description of what was read."""
    if not path.exists():
        raise UserError(f"{path}: no such file; give a capture (.cap) or a record (.txt)")
    try:
        if path.suffix.lower() == ".txt":
            t_s, data, temp, source = load_record(path)
            rec = Record(path.stem, t_s * 1000.0, data[:, :3], data[:, 3:], temp)
            sys.stderr.write(timing_report({path.stem: rec}))
            an = recording.analyse(t_s, data, temp, remove_thermal=remove_thermal, ci=ci)
            return an, source
        from host.cli.noise_source import CaptureSamples, FilePhases

        with tempfile.TemporaryDirectory(prefix="imu-bench-noise-") as tmp:
            work = Path(tmp)
            samples = CaptureSamples(path, work)
            sys.stderr.write(quality_report(path.stem, samples.timing()))
            an = recording.analyse_blocks(
                samples, remove_thermal=remove_thermal, ci=ci, phases=lambda: FilePhases(work)
            )
            return an, samples.note
    except ValueError as exc:
        raise UserError(f"{path}: {exc}; record longer") from None
    except OSError as exc:  # the temporary files (about 70 bytes a sample)
        raise UserError(
            f"{path}: cannot write the temporary files a capture is streamed through in "
            f"{tempfile.gettempdir()} ({exc.strerror or exc}); free space there or set TMPDIR"
        ) from None


def _fmt(v: float) -> str:
    return f"{v:.3g}"


def _figure_cell(channel: str, q: str, f: allan.Figure) -> str:
    """A figure in its display unit (named in the column's header): value [interval], or
    '< bound' when the recording does not resolve it."""
    if f.value is None:
        return f"< {_fmt(recording.display_units(channel, q, f.ci[1])[0])}"
    v, _ = recording.display_units(channel, q, f.value)
    lo, _ = recording.display_units(channel, q, f.ci[0])
    hi, _ = recording.display_units(channel, q, f.ci[1])
    return f"{_fmt(v)} [{_fmt(lo)}, {_fmt(hi)}]"


#: the three figures' names in the table's header
_HEADS = {"white_noise_density": "white noise", "bias_instability": "bias instability",
          "rate_random_walk": "rate random walk"}  # fmt: skip


def format_text(an: recording.NoiseAnalysis, source: str, width: int = 80) -> str:
    """The human summary: per sensor a table, a row per channel, a column per figure (its
    unit in the header; a second unit where users quote two, left out first when narrow)."""
    lines = [
        f"{source}: {an.duration_s / 60:.1f} min at {an.rate_hz:.2f} Hz; "
        f"{100 * an.ci:.0f} % confidence intervals; temperature span {an.span_c:.1f} °C"
    ]
    for sensor in ("accel", "gyro"):
        names = [n for n in an.channels if allan.sensor_of(n) == sensor]
        if not names:
            continue
        cols = [Column(sensor, names, align="<")]
        for q in allan.QUANTITIES:
            unit = recording.display_units(names[0], q, 1.0)[1]
            cells = [_figure_cell(n, q, an.channels[n].figures[q]) for n in names]
            cols.append(Column(f"{_HEADS[q]}, {unit}", cells, align="<"))
            if q == "white_noise_density" and sensor == "accel":
                second = [recording.secondary_units(n, q, an.channels[n].figures[q].value or 0.0)
                          for n in names]  # fmt: skip
                if second[0] is not None:
                    resolved = [an.channels[n].figures[q].value is not None for n in names]
                    cells2 = [_fmt(x[0]) if x is not None and ok else "—"
                              for x, ok in zip(second, resolved, strict=True)]  # fmt: skip
                    cols.append(Column(f"VRW, {second[0][1]}", cells2, align="<", rank=1))
        lines += [""] + table(cols, width)
    if any(f.value is None for ch in an.channels.values() for f in ch.figures.values()):
        lines.append("< bound: not resolved in this recording, an upper bound (warnings below)")
    lines.append("")
    for name, ch in an.channels.items():
        taus = [
            f"{q.split('_')[0]} at τ = {ch.figures[q].tau_s:.3g} s"
            for q in allan.QUANTITIES
            if ch.figures[q].tau_s is not None
        ]
        lines.append(f"  {name} read: " + ", ".join(taus))
    for w in an.warnings:
        lines.append(f"warning: {w}")
    return "\n".join(lines) + "\n"


def _duration_text(s: float | None) -> str:
    if s is None:
        return "not reachable (the term does not dominate at any tau in this model)"
    if s >= 86400:
        return f"{s / 86400:.1f} days"
    if s >= 3600:
        return f"{s / 3600:.1f} h"
    if s >= 120:
        return f"{s / 60:.0f} min"
    return f"{s:.0f} s"


def parse_precision(text: str) -> float:
    """'10%' or '0.1' -> 0.1."""
    t = text.strip()
    try:
        v = float(t[:-1]) / 100.0 if t.endswith("%") else float(t)
    except ValueError:
        v = math.nan
    if not (0 < v < 1):
        raise UserError(f"--plan: expected a relative precision like 10% or 0.1, got {text!r}")
    return v


@dataclass(frozen=True)
class NoiseOptions:
    """``noise``: the recording, the figures as JSON on stdout, the plot (a PNG), the
    relative precision to plan the recording for (its text: 10% or 0.1), the confidence
    level, a drift following the temperature kept, the noise file to write."""

    file: str
    json: bool = False
    plot: str | None = None
    plan: str | None = None
    ci: float = allan.CI_LEVEL
    keep_thermal: bool = False
    save: str | None = None


def noise_options(ns: argparse.Namespace) -> NoiseOptions:
    """The ``noise`` options from its arguments."""
    return NoiseOptions(file=ns.file, json=ns.json, plot=ns.plot, plan=ns.plan, ci=ns.ci,
                        keep_thermal=ns.keep_thermal, save=ns.save)  # fmt: skip


def run(args: NoiseOptions) -> int:
    """Runner of ``python3 -m host noise``."""
    path = Path(args.file)
    if not 0.5 <= args.ci < 1:
        raise UserError(f"--ci: expected a confidence level between 0.5 and 1, got {args.ci}")
    precision = parse_precision(args.plan) if args.plan else None
    an, source = analyse_file(path, not args.keep_thermal, args.ci)
    doc = an.as_dict()
    doc["source"] = str(path)
    if precision is not None:
        plan = recording.plan(an, precision)
        doc["plan"] = {"precision": precision, "duration_s": plan}
    if args.save:
        write_text_atomic(args.save, json.dumps(doc, indent=2) + "\n")
    if args.plot:
        plt = pyplot()
        fig = noise_figure(an, path.name)
        fig.savefig(Path(args.plot), dpi=DPI)
        plt.close(fig)
    if args.json:
        sys.stdout.write(json.dumps(doc, indent=2) + "\n")
    else:
        sys.stdout.write(format_text(an, f"{path.name}: {source}", terminal_width(sys.stdout)))
        if precision is not None:
            print(f"plan: to get each figure to +-{100 * precision:.0f} % "
                  f"({100 * an.ci:.0f} % interval), record at least")  # fmt: skip
            for q, per in doc["plan"]["duration_s"].items():
                worst = max((v for v in per.values() if v is not None), default=None)
                missing = [c for c, v in per.items() if v is None]
                text = f"  {q.replace('_', ' '):20} {_duration_text(worst)}"
                if missing and worst is not None:
                    text += f" (not reachable for {', '.join(missing)})"
                print(text)
    for p in (args.save, args.plot):
        if p:
            print(f"written: {p}", file=sys.stderr)
    return 0


def cli_noise(p: argparse.ArgumentParser) -> Command[NoiseOptions]:
    """Fill in the ``noise`` subparser; returns the command."""
    p.add_argument("file", help="a static recording: capture (.cap) or record file (.txt)")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    p.add_argument("--plot", metavar="PNG", help="write the log-log Allan deviation plot")
    p.add_argument(
        "--plan",
        metavar="PRECISION",
        help="how long to record for each figure to this relative precision (e.g. 10%%)",
    )
    p.add_argument(
        "--ci", type=float, default=allan.CI_LEVEL, help="confidence level (default 0.95)"
    )
    p.add_argument(
        "--keep-thermal",
        action="store_true",
        help="do not remove a drift that follows the chip temperature (it is always reported)",
    )
    p.add_argument(
        "--save",
        metavar="FILE",
        help="write the noise file (the --json document; e.g. SERIAL_noise.json for the "
        "workbench's noise floor)",
    )
    return Command(noise_options, run, data_out=lambda o: o.json)
