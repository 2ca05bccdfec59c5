"""``python3 -m host thermal DIR``: bias against chip temperature from the warm-up, static and
thermal-ramp records of a unit (:mod:`host.calib.thermal_fit`), written as ``SERIAL_thermal.json``
(:mod:`host.calib.thermal`), and its plot.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from host.calib import thermal, thermal_fit
from host.cli import out_directory, pyplot
from host.cli.figures import DPI, shown_unit, thermal_figure
from host.cli.options import Command
from host.errors import UserError
from host.session.atomic import write_text_atomic
from host.session.directory import read_record, read_session, split_file_name
from host.session.records import WARMUP_NAME, Record, RecordError
from host.session.spacing import timing_report

#: exponents as people write them (°C²)
_POWER = {1: "", 2: "²", 3: "³", 4: "⁴", 5: "⁵", 6: "⁶"}


def format_text(cal: thermal.ThermalCalibration) -> str:
    """The human summary: per channel the order chosen, the coefficients, and on a second line
    the change over the valid range and the residual (each line within 80 columns)."""
    lines = [
        f"thermal calibration of {cal.serial}: valid {cal.t_min_c:.1f} to {cal.t_max_c:.1f} °C,",
        f"bias change relative to T_ref = {cal.t_ref_c:.2f} °C",
        f"attitudes: {', '.join(cal.attitudes)}",
    ]
    for name, ch in cal.channels.items():
        unit = shown_unit(ch.unit)
        terms = (
            ", ".join(
                f"c{j} = {c:+.4g} {unit}/°C{_POWER.get(j, f'^{j}')}"
                for j, c in enumerate(ch.coef, start=1)
            )  # fmt: skip
            or "no temperature dependence"
        )
        full = ch.delta(np.array([cal.t_min_c, cal.t_max_c]), cal.t_ref_c)
        lines.append(f"{name}  order {ch.order}: {terms}")
        lines.append(
            f"    change over the range {full[0]:+.4g} .. {full[1]:+.4g} {unit}; "
            f"residual rms {ch.rms:.3g} {unit}"
        )
        if ch.scale_order:
            sc = ", ".join(f"s{q} = {c:+.4g}/°C{_POWER.get(q, f'^{q}')}"
                           for q, c in enumerate(ch.scale_coef, 1))  # fmt: skip
            ends = ch.scale_delta(np.array([cal.t_min_c, cal.t_max_c]), cal.t_ref_c)
            lines.append(f"{name}  scale order {ch.scale_order}: {sc}")
            lines.append(
                f"    scale change over the range {100 * ends[0]:+.3f} .. {100 * ends[1]:+.3f} %"
            )
    return "\n".join(lines) + "\n"


def unit_records(directory: str, serial: str | None) -> tuple[str, list[Record]]:
    """The serial and the static records of one unit in ``directory``: its warm-up
    (``SERIAL_warmup.txt``) first, then its static and thermal records — or the warm-up alone
    when the directory holds no other record of it."""
    warmups = {
        parts[0]: p
        for p in sorted(Path(directory).glob(f"*_{WARMUP_NAME}.txt"))
        if (parts := split_file_name(p)) is not None and parts[1] == WARMUP_NAME
    }
    try:
        session = read_session(directory, serial)
    except RecordError:
        only = [s for s in warmups if serial in (None, s)]
        if len(only) != 1:
            raise
        return only[0], [read_record(warmups[only[0]])]
    records = [r for r in session.records.values() if r.kind != "turn"]
    if session.serial in warmups:
        records.insert(0, read_record(warmups[session.serial]))
    return session.serial, records


@dataclass(frozen=True)
class ThermalOptions:
    """``thermal``: the records' directory and serial (None: from the file names), the
    polynomial order (None: chosen up to ``max_order``), the scale fitted too, the averaging
    window, s, where the result goes (None: the records' directory), the plot (a PNG, None:
    none), the result as JSON on stdout."""

    dir: str
    serial: str | None = None
    order: int | None = None
    max_order: int = thermal_fit.MAX_ORDER
    scale: bool = False
    window: float = 20.0
    out: str | None = None
    plot: str | None = None
    json: bool = False


def thermal_options(ns: argparse.Namespace) -> ThermalOptions:
    """The ``thermal`` options from its arguments."""
    return ThermalOptions(
        dir=ns.dir, serial=ns.serial, order=ns.order, max_order=ns.max_order, scale=ns.scale,
        window=ns.window, out=ns.out, plot=ns.plot, json=ns.json,
    )  # fmt: skip


def run(args: ThermalOptions) -> int:
    """Runner of ``python3 -m host thermal``."""
    serial, records = unit_records(args.dir, args.serial)
    sys.stderr.write(timing_report({r.name: r for r in records}))
    if args.order is not None and not 0 <= args.order <= 6:
        raise UserError("--order must be between 0 and 6")
    if not 0 <= args.max_order <= 6:
        raise UserError("--max-order must be between 0 and 6")
    if not args.window > 0:
        raise UserError("--window must be a positive number of seconds")
    cal, pts = thermal_fit.fit_thermal(
        records, serial, order=args.order, max_order=args.max_order, window_s=args.window,
        scale=True if args.scale else None,
    )  # fmt: skip
    out_dir = out_directory(args.out) if args.out else Path(args.dir)
    path = out_dir / f"{serial}_thermal.json"
    write_text_atomic(path, cal.to_json())
    if args.plot:
        plt = pyplot()
        fig = thermal_figure(cal, pts)
        fig.savefig(args.plot, dpi=DPI)
        plt.close(fig)
    sys.stdout.write(cal.to_json() if args.json else format_text(cal))
    print(f"written: {path}" + (f" and {args.plot}" if args.plot else ""), file=sys.stderr)
    return 0


def cli_thermal(p: argparse.ArgumentParser) -> Command[ThermalOptions]:
    """Fill in the ``thermal`` subparser; returns the command."""
    p.add_argument("dir", help="directory of the unit's records (warm-up, static, thermal ramp)")
    p.add_argument("--serial", help="serial number (default: from the file names)")
    p.add_argument("--order", type=int, help="fix the polynomial order (default: chosen)")
    p.add_argument(
        "--max-order",
        type=int,
        default=thermal_fit.MAX_ORDER,
        help="highest order tried (default 4)",
    )
    p.add_argument(
        "--scale",
        action="store_true",
        help="fit every accelerometer axis's scale against temperature, or say which records "
        "are missing (default: fitted where the attitudes allow — the axis up and down across "
        "the span)",
    )
    p.add_argument("--window", type=float, default=20.0, help="averaging window, s (default 20)")
    p.add_argument(
        "--out",
        metavar="DIR",
        help="where to write SERIAL_thermal.json (default DIR; made if missing)",
    )
    p.add_argument("--plot", metavar="PNG", help="bias against temperature with curve and band")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    return Command(thermal_options, run, data_out=lambda o: o.json)
