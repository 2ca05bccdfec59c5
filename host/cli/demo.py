"""``python3 -m host demo hidden-effect``: a simulated session with ONE physical effect hidden
from the fit (:mod:`host.workbench.scenarios`), and the workbench finding it — what it names,
and how close its coefficient comes to the truth; the commands that repeat its numbers on its
records (:mod:`host.cli.model`).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

from host.calib.commands import command_lines
from host.cli.options import Command
from host.cli.screen import terminal_width, working
from host.errors import UserError
from host.workbench.scenarios import DEFAULT_EFFECTS, EFFECTS, hidden_effect_case, run_case
from host.workbench.text import format_case, format_outcome


class _Renamed(argparse.Action):
    """An option's old spelling: still works, with a note naming the new one."""

    def __init__(self, *args: Any, new: str, **kw: Any) -> None:
        self.new = new
        super().__init__(*args, **kw)

    def __call__(self, parser: Any, ns: argparse.Namespace, values: Any, opt: Any = None) -> None:
        print(f"note: {opt} is now {self.new} (the old spelling still works)", file=sys.stderr)
        setattr(ns, self.dest, values)


@dataclass(frozen=True)
class DemoOptions:
    """``demo hidden-effect``: the effect (or all), the simulation's seed, where the records
    go (None: not written), the 12 45° attitudes added, the static records' length, s."""

    effect: str = "all"
    seed: int = 1
    out: str | None = None
    tilted: bool = False
    static_s: float = 10.0


def demo_options(ns: argparse.Namespace) -> DemoOptions | None:
    """The ``demo`` options (None: no demo chosen)."""
    if ns.demo_command != "hidden-effect":
        return None
    return DemoOptions(effect=ns.effect, seed=ns.seed, out=ns.out, tilted=ns.tilted,
                       static_s=ns.static_s)  # fmt: skip


def run_demo(args: DemoOptions) -> int:
    effects = DEFAULT_EFFECTS if args.effect == "all" else (args.effect,)
    for eff in effects:
        if eff not in EFFECTS:
            raise UserError(f"unknown effect {eff!r}; known: all, {', '.join(EFFECTS)}")
    width = terminal_width(sys.stdout)
    for eff in effects:
        case = hidden_effect_case(eff, args.seed, tilted=args.tilted, static_s=args.static_s)
        print(format_case(case))
        # the unit's noise known, as from a noise file (--noise): the floor does not carry
        # the hidden effect the way the session's repeated attitudes would. The commands below
        # give that floor, so that they print the figures printed here.
        floor = ",".join(f"{s}={v:.6g}" for s, v in sorted(case.known_floor.items()))
        print(f"noise floor of a record mean: {floor.replace(',', ', ')} (the unit's, known: "
              "as a noise file gives it; --floor below gives the same)")  # fmt: skip
        with working(f"demo {eff}: diagnosing the simulated session"):
            outcome = run_case(case, case.known_noise())
        try_line = None
        if args.out:
            from host.bench.plan import write_session

            out = Path(args.out) / eff
            write_session(out, "DEMO", dict(case.records))
            cmd = ["python3", "-m", "host", "model", "diagnose", str(out), "--floor", floor]
            print(f"records written to {out}; the same diagnosis:")
            print(command_lines(cmd, width, lead="  "))
            spec = outcome.diagnosis.recommended_spec
            if spec:
                add = ["python3", "-m", "host", "model", "add", str(out), spec, "--floor", floor]
                try_line = command_lines(add, width, lead="  try: ")
        print(format_outcome(outcome, try_line=try_line))
        print()
    return 0


def cli_demo(p: argparse.ArgumentParser) -> Command[DemoOptions | None]:
    """``demo hidden-effect``."""
    sub = p.add_subparsers(dest="demo_command", metavar="DEMO", title="demos")
    text = ("simulate a session with one effect hidden from the fit and let the workbench "
            "find it: what it names, and how close its coefficient comes to the truth")  # fmt: skip
    h = sub.add_parser(
        "hidden-effect", help="an effect hidden in a simulated session, found by the workbench",
        description=text, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  python3 -m host demo hidden-effect --effect temperature --seed 4\n"
        "  python3 -m host demo hidden-effect --out /tmp/demo\n      every effect, records kept",
    )  # fmt: skip
    h.add_argument("--effect", default="all", help=f"all (default) or one of {', '.join(EFFECTS)}")
    h.add_argument("--seed", type=int, default=1, help="simulation seed (default 1)")
    h.add_argument("--out", default=None, help="also write the records to OUT/EFFECT/")
    h.add_argument("--tilted", action="store_true", help="add the 12 45° attitudes")
    h.add_argument("--static-seconds", type=float, default=10.0, dest="static_s", metavar="S",
                   help="static record length, s (as in calibrate; default 10)")  # fmt: skip
    h.add_argument("--static-s", type=float, dest="static_s", action=_Renamed,
                   new="--static-seconds", help=argparse.SUPPRESS)  # fmt: skip

    return Command(demo_options, partial(_demo_or_help, p))


def _demo_or_help(p: argparse.ArgumentParser, o: DemoOptions | None) -> int:
    """Runner of ``demo``: the demo chosen, or the help (exit status 2) without one."""
    if o is None:
        p.print_help()
        return 2
    return run_demo(o)
