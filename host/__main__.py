"""``python3 -m host COMMAND ...``: the thin command line.

Each command lives in the module of its stage; this file only maps command names to
``module:function`` pairs. The function is called with the subparser to fill in and
returns the command (:class:`host.cli.options.Command`): how its typed options are read
from the parsed arguments, and the runner that takes them (``run(options) -> int``).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys
from typing import TYPE_CHECKING, Any, NoReturn

#: numpy's BLAS starts a thread per core; the fits here are small, and on a shared or loaded
#: machine those threads fight each other and every other process for the cores (a 2-core
#: machine under load ran ``model add`` 20x slower). One thread unless the user set a number.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
for _name in BLAS_THREAD_VARIABLES:
    os.environ.setdefault(_name, "1")

from host.errors import UserError  # noqa: E402  (after the BLAS setting: numpy reads it once)

if TYPE_CHECKING:
    from host.cli.options import Command

#: command -> (module, function adding the arguments and returning the runner, one-line help)
COMMANDS: dict[str, tuple[str, str, str]] = {
    "calibrate": ("host.cli.calibrate", "cli_calibrate", "compute calibration, write the report"),
    "import": (
        "host.cli.importing",
        "cli_import",
        "turn a foreign file (columns, imucal session, .cap) into record files",
    ),
    "export": (
        "host.cli.exporting",
        "cli_export",
        "write a result as ArduPilot/PX4 parameters, imucal JSON or a C header",
    ),
    "decode": ("host.cli.decode", "cli_decode", "decode a capture file to JSONL/CSV samples"),
    "capture": (
        "host.cli.capture",
        "cli_capture",
        "record a port's bytes with host times to a file",
    ),
    "model": ("host.cli.model", "cli_model", "model workbench: diagnose, add a term, ladder"),
    "demo": ("host.cli.demo", "cli_demo", "demo: find an effect hidden in a simulated session"),
    "thermal": (
        "host.cli.thermal",
        "cli_thermal",
        "bias against chip temperature from warm-up and thermal-ramp records",
    ),
    "plan": (
        "host.cli.plan",
        "cli_plan",
        "which record to measure next: ranked by σ/tolerance per minute",
    ),
    "noise": (
        "host.cli.noise",
        "cli_noise",
        "Allan deviation of a static recording: noise figures, plot, recording planner",
    ),
    "archive": (
        "host.cli.archive",
        "cli_archive",
        "every calibration kept by serial: list, trend, repeat, drift, lot, bench check",
    ),
    "flash": (
        "host.cli.flash",
        "cli_flash",
        "build, flash and verify the firmware (avrdude), then check its hello",
    ),
}


EXIT_CODES = """exit status:
  0    done (calibrate: every value within tolerance)
  1    calibrate: some value outside tolerance or not measured
  2    bad input or a problem to fix (one line on stderr says which)
  130  interrupted (Ctrl+C; 143 SIGTERM, 129 SIGHUP)"""

#: command -> examples shown at the end of its --help
EXAMPLES: dict[str, str] = {
    "calibrate": """examples:
  python3 -m host calibrate --serial DEMO01 --yes --warmup 0 --static-seconds 5 --turns 1
      a whole session on the virtual board (no board plugged in)
  python3 -m host calibrate --port /dev/ttyACM0 --serial U17
      the guided dialogue on a real APM 2.6
  python3 -m host calibrate --port /dev/ttyACM0 --serial U17 --out U17 --resume
      continue an interrupted session (Ctrl+C prints this command, with every option)
  python3 -m host calibrate --port /dev/ttyACM0 --serial U17 --out U17 --redo x_ccw
      measure one record again, keep the others
  python3 -m host calibrate --port /dev/ttyACM0 --serial U17 --no-self-test
      skip the sensor's self-test (recorded as not run; the verdict says so)
  python3 -m host calibrate --port /dev/ttyACM0 --serial U17 --port /dev/ttyACM1 --serial U18
      two boards in one cube, one dialogue: U17/ and U18/ (with --out DIR: DIR/U17/ …)
  python3 -m host calibrate --from-dir U17/
      recompute the report from saved records
  python3 -m host calibrate --from-dir U17/ --decision-rule simple
      mark each value by its value alone, U not used (default guarded: value ± U)""",
    "capture": """examples:
  python3 -m host capture --port /dev/ttyACM0 session.cap
      until Ctrl+C
  python3 -m host capture --port "sim://?speed=10" --seconds 5 s.cap""",
    "decode": """examples:
  python3 -m host decode session.cap --jsonl | head
  python3 -m host decode session.cap --stats""",
    "model": """examples:
  python3 -m host model diagnose DIR --plot plots/
  python3 -m host model add DIR temperature_bias:gyro:x""",
    "archive": """examples:
  python3 -m host archive add U17/
      keep U17's result in your archive
  python3 -m host archive repeat U17
      do its calibrations agree within σ?
  python3 -m host archive drift
      which units moved: recalibrate
  python3 -m host archive lot --archive postgresql://qc@db/line
  python3 -m host archive check-bench REF01
      compare the benches on a reference unit""",
    "plan": """examples:
  python3 -m host plan U17/
      the next record that buys the most precision
  python3 -m host plan U17/ --model base,temperature_bias:gyro --top 5
  python3 -m host plan U17/ --separate scale_asymmetry:gyro:z scale_nonlinearity:gyro:z
      the record that tells two explanations apart""",
    "demo": """examples:
  python3 -m host demo hidden-effect --effect temperature --seed 4 --out /tmp/demo""",
    "import": """examples:
  python3 -m host import logger.csv --columns t,temp,ax,ay,az,gx,gy,gz \\
      --units t=ms,accel=g,gyro=rad/s --axes x,-y,-z --serial LOG1 --out LOG1/
  python3 -m host import session.cap --serial U17 --out U17/
      a capture, cut into records""",
    "thermal": """examples:
  python3 -m host thermal U17/ --plot U17_thermal.png
      bias(T) from warm-up and statics
  python3 -m host thermal U17/ --window 5
      records of 10 s: 5 s windows""",
    "noise": """examples:
  python3 -m host noise U17/U17_x_up.txt --plot allan.png
      the figures and their plot
  python3 -m host noise long.cap --save U17_noise.json
      the noise file of the unit
  python3 -m host noise long.cap --plan 10%
      how long to record""",
    "flash": """examples:
  python3 -m host flash --port /dev/ttyACM0
      build, flash, check the HELLO
  python3 -m host flash --port 'emu://?flash=board.flash'
      the emulated board, no hardware""",
    "export": """examples:
  python3 -m host export U17/ --to ardupilot --out U17.parm
  python3 -m host export U17/ --to px4 --axes x,-y,-z
      the board's axes
  python3 -m host export U17/ --to c-header --allow-fail
      a FAILED result, marked so
  python3 -m host export U17/ --to ardupilot --thermal
      with INS_TCAL1_* from bias(T)""",
}


class WholeWords(argparse.RawDescriptionHelpFormatter):
    """Help text wrapped at spaces only ("imu-bench" is not cut at its hyphen); description
    and examples keep their lines, a line too long for the terminal wrapped under its indent,
    an example's command kept whole on lines of its own (:func:`host.cli.screen.
    help_examples`)."""

    def _split_lines(self, text: str, width: int) -> list[str]:
        import textwrap

        return textwrap.wrap(" ".join(text.split()), width, break_on_hyphens=False,
                             break_long_words=False)  # fmt: skip

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        from host.cli.screen import help_examples

        return help_examples("\n".join(indent + line for line in text.splitlines()), width + 2)


class OneLineErrors(argparse.ArgumentParser):
    """A parser whose mistakes are one line naming the problem and where the help is (not the
    usage dump); subcommand parsers are of this class too, and all wrap their help at words."""

    def __init__(self, *args: Any, **kw: Any) -> None:
        kw["formatter_class"] = WholeWords
        super().__init__(*args, **kw)

    def error(self, message: str) -> NoReturn:
        shown = message.replace("\r", "\\r").replace("\n", "\\n")  # one line, whatever was typed
        import re

        m = re.match(r"argument (--[\w-]+).*: expected one argument", shown)
        if m:  # its value starts with '-' (--axes -x,y,z): argparse took it for an option
            shown += f"; a value starting with '-' goes as {m.group(1)}=VALUE"
        self.exit(2, f"error: {shown} (see: {self.prog} --help)\n")


def leaf_parser(
    parser: argparse.ArgumentParser, args: argparse.Namespace
) -> argparse.ArgumentParser:
    """The parser of the subcommand ``args`` chose (``model ladder``'s for ``model ladder``)."""
    chosen = vars(args)
    while True:
        acts = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if not acts or chosen.get(acts[0].dest) not in acts[0].choices:
            return parser
        parser = acts[0].choices[chosen[acts[0].dest]]


def empty_word(words: list[str]) -> str | None:
    """What is wrong when a word of the command line is empty (``--out ""``, ``--out=``, an
    empty argument: an unset shell variable, most often), else None: no command reads an
    empty word as a value ('' as a path is the current directory)."""
    for i, w in enumerate(words):
        if w.startswith("--") and w.endswith("=") or w == "":
            opt = w[:-1] if w else words[i - 1] if i and words[i - 1].startswith("--") else ""
            why = "(an unset variable?)"
            if opt:
                return f"{opt} '': an empty value {why}; give one, or leave {opt} out"
            return f"'': an empty argument {why}; give what it stands for"
    return None


def _version() -> str:
    from host.version import __version__
    from host.wire.protocol_gen import PROTOCOL_VERSION, SPEC_FINGERPRINT

    return f"imu-bench {__version__} (protocol {PROTOCOL_VERSION}, spec {SPEC_FINGERPRINT:#010x})"


def build_parser(
    only: str | None = None,
) -> tuple[argparse.ArgumentParser, dict[str, Command[Any]]]:
    """The parser and the commands (:class:`host.cli.options.Command`); with ``only``, the
    arguments and the command of that command alone (the others are listed, their modules
    not imported: start-up imports what the command needs)."""
    parser = OneLineErrors(
        prog="python3 -m host", description="IMU calibration bench host (APM 2.6 / MPU-6000).",
        epilog=EXIT_CODES,
    )  # fmt: skip
    parser.add_argument("--version", action="version", version=_version())
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    runners: dict[str, Command[Any]] = {}
    for name, (module, func, help_text) in COMMANDS.items():
        # the exit codes once, at the top and for calibrate (whose 0 and 1 are the verdict)
        codes = EXIT_CODES if name == "calibrate" else ""
        epilog = "\n\n".join(x for x in (EXAMPLES.get(name, ""), codes) if x)
        p = sub.add_parser(
            name, help=help_text, description=help_text, epilog=epilog,
        )  # fmt: skip
        if only is None or name == only:
            runners[name] = getattr(importlib.import_module(module), func)(p)
    return parser, runners


#: commands whose stdout is data for programs (samples, a parameter file, JSON): not wrapped
MACHINE_STDOUT = ("decode", "export", "capture")


def main(argv: list[str] | None = None) -> int:
    from host.cli.screen import ScreenWriter

    raw_out, raw_err = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = ScreenWriter(raw_out), ScreenWriter(raw_err)
    try:
        return _run(argv, raw_out)
    except BrokenPipeError:  # the reader of stdout went away (| head): end quietly
        return _reader_gone()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except BrokenPipeError:
                _reader_gone()
        sys.stdout, sys.stderr = raw_out, raw_err


def _reader_gone() -> int:
    """What is still to be written to a closed pipe goes nowhere (not a second error as
    Python ends); the command ends quietly, as ``head`` asked: exit status 0."""
    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.__stdout__.fileno() if sys.__stdout__ else 1)
    return 0


def _run(argv: list[str] | None, raw_out: object) -> int:
    from host.cli.options import OptionError

    words = sys.argv[1:] if argv is None else argv
    command = next((w for w in words if not w.startswith("-")), None)
    parser, runners = build_parser(command or "")  # no command: no command's module
    args, extra = parser.parse_known_args(argv)
    if extra:  # said by the subcommand that does not know them, with its help
        leaf_parser(parser, args).error(f"unrecognized arguments: {' '.join(extra)}")
    empty = empty_word(words)
    if empty is not None:  # was: '' read as '.', records written into the current directory
        print(f"error: {empty}", file=sys.stderr)
        return 2
    if not args.command:
        parser.print_help()
        return 2
    chosen = runners[args.command]
    try:
        try:
            options = chosen.options(args)
        except OptionError as exc:  # a value on the command line: said with the help to read
            leaf_parser(parser, args).error(str(exc))
        if args.command in MACHINE_STDOUT or chosen.data_out(options):
            sys.stdout.flush()
            sys.stdout = raw_out  # type: ignore[assignment]
        return chosen.run(options)
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # not a file of the command's: its reader stopped reading
        raise
    except OSError as exc:  # one a command did not put in its words: its file and its cause
        where = f"{exc.filename}: " if exc.filename else ""
        what = (exc.strerror or str(exc)).lower()
        print(f"error: {where}{what}; check the path, then run again", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
