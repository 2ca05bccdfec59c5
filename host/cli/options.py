"""The commands' edge: each command's options read once from argparse into a typed, frozen
options object (:class:`Command`), and the argument groups commands share — the model and
its term files, the noise floor, the site, the archive — each added by one function and read
back by its twin.

A command module's ``cli_NAME(parser)`` adds its arguments and returns a :class:`Command`:
``options(namespace)`` builds the command's options (an :class:`OptionError` is a mistake on
the command line, said with the help to read; another UserError as any other), ``run(options)``
runs it. Nothing else reads the argparse namespace.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Generic, TypeVar

from host.errors import UserError
from host.session.method import DEFAULT_HEIGHT_M, DEFAULT_LATITUDE_DEG

T = TypeVar("T")


class OptionError(UserError):
    """A value on the command line that cannot work: said as a parser error (one line, with
    where the help is)."""


def _no_data(_options: object) -> bool:
    return False


@dataclass(frozen=True)
class Command(Generic[T]):
    """One command: ``options`` reads its options from the parsed arguments, ``run`` runs
    it with them and returns the exit status; ``data_out(options)``: its stdout is data for
    programs (JSON), not text wrapped to the terminal."""

    options: Callable[[argparse.Namespace], T]
    run: Callable[[T], int]
    data_out: Callable[[T], bool] = _no_data

    def __call__(self, ns: argparse.Namespace) -> int:
        """Read the options and run (what a caller without the edge's handling does)."""
        return self.run(self.options(ns))


# ---------------------------------------------------------------------------- the model


@dataclass(frozen=True)
class ModelOptions:
    """``--model`` (a model spec, :func:`host.model.spec.parse_model`), the ``--term-file``
    Python files defining extra terms, and how long their code may run, s (None: the
    loader's default)."""

    spec: str = "base"
    term_files: tuple[str, ...] = ()
    term_timeout_s: float | None = None

    def bound_term_files(self) -> None:
        """Give the term files' code the time ``--term-timeout`` says (before any is read)."""
        if self.term_timeout_s is not None:
            from host.model import loader

            loader.TIME_LIMIT_S = self.term_timeout_s


MODEL_SPEC_HELP = (
    "comma list of term[:sensor[:axes]] (default base = bias,scale,misalignment,"
    "g_sensitivity, method.md §2)"
)


def add_model_options(p: argparse.ArgumentParser, lead: str = "") -> None:
    """--model (its help after ``lead``), --term-file, --term-timeout."""
    p.add_argument("--model", default="base", help=lead + MODEL_SPEC_HELP)
    p.add_argument(
        "--term-file", action="append", default=[], metavar="F",
        help="Python file defining extra terms for --model (repeatable)",
    )  # fmt: skip
    p.add_argument(
        "--term-timeout", type=float, metavar="S",
        help="how long the term files' code may run, s (default 120; a progress line every 5 s)",
    )  # fmt: skip


def model_options(ns: argparse.Namespace) -> ModelOptions:
    """The options :func:`add_model_options` added; OptionError for a time bound not above 0."""
    timeout = ns.term_timeout
    if timeout is not None and not timeout > 0:
        raise OptionError("--term-timeout: give a number of seconds above 0")
    return ModelOptions(spec=ns.model, term_files=tuple(ns.term_file), term_timeout_s=timeout)


# ---------------------------------------------------------------------------- the floor


@dataclass(frozen=True)
class FloorOptions:
    """The noise floor of a record mean: ``floor`` the ``--floor accel=A,gyro=G`` text,
    ``noise`` the unit's noise file (either None: from the other, else measured)."""

    floor: str | None = None
    noise: str | None = None


def add_floor_options(p: argparse.ArgumentParser) -> None:
    """--floor and --noise."""
    p.add_argument(
        "--floor", default=None, metavar="accel=A,gyro=G",
        help="bias-instability floor of a record mean (m/s², °/s), e.g. accel=5e-4,gyro=3e-3; a "
        "sensor not given comes from --noise, else from the records' own samples (the wander of "
        "their block means beyond white noise)",
    )  # fmt: skip
    p.add_argument(
        "--noise", default=None, metavar="NOISE.json",
        help="noise file of this unit (python3 -m host noise FILE --save NOISE.json): the floor "
        "is its Allan variance at the static records' length without the white part",
    )  # fmt: skip


def floor_options(ns: argparse.Namespace) -> FloorOptions:
    """The options :func:`add_floor_options` added."""
    return FloorOptions(floor=ns.floor, noise=ns.noise)


# ---------------------------------------------------------------------------- the site


@dataclass(frozen=True)
class Site:
    """Where the unit is measured: latitude, degrees, and height above sea level, m (local
    gravity and the Earth's rate follow from them)."""

    latitude_deg: float = DEFAULT_LATITUDE_DEG
    height_m: float = DEFAULT_HEIGHT_M

    def words(self) -> list[str]:
        """The options that say this site, where it is not the default one."""
        words: list[str] = []
        if self.latitude_deg != DEFAULT_LATITUDE_DEG:
            words += ["--latitude", f"{self.latitude_deg}"]
        if self.height_m != DEFAULT_HEIGHT_M:
            words += ["--height", f"{self.height_m}"]
        return words


def add_site_options(p: argparse.ArgumentParser) -> None:
    """--latitude and --height."""
    p.add_argument(
        "--latitude", type=float,
        help=f"site latitude, degrees (default {DEFAULT_LATITUDE_DEG})",
    )  # fmt: skip
    p.add_argument(
        "--height", type=float,
        help=f"site height above sea level, m (default {DEFAULT_HEIGHT_M:g})",
    )  # fmt: skip


def site_options(ns: argparse.Namespace) -> Site:
    """The options :func:`add_site_options` added (the default site where one is not given;
    ``calibrate`` reads them itself: its report says where the site came from)."""
    lat = DEFAULT_LATITUDE_DEG if ns.latitude is None else ns.latitude
    return Site(latitude_deg=lat, height_m=DEFAULT_HEIGHT_M if ns.height is None else ns.height)


# ---------------------------------------------------------------------------- the workbench


@dataclass(frozen=True)
class WorkbenchOptions:
    """What the workbench's commands (``model diagnose|add|ladder``, ``plan``) share: the
    records' directory and serial (None: the only one there), the model and its term files,
    the noise floor, the site, JSON on stdout."""

    dir: str
    serial: str | None = None
    model: ModelOptions = field(default_factory=ModelOptions)
    floor: FloorOptions = field(default_factory=FloorOptions)
    site: Site = field(default_factory=Site)
    json: bool = False


def add_workbench_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of :class:`WorkbenchOptions`."""
    p.add_argument("dir", help="directory with the records SERIAL_name.txt")
    add_model_options(p)
    p.add_argument("--serial", default=None, help="serial whose records to use")
    add_floor_options(p)
    add_site_options(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")


def workbench_options(ns: argparse.Namespace) -> WorkbenchOptions:
    """The options :func:`add_workbench_arguments` added."""
    return WorkbenchOptions(
        dir=ns.dir, serial=ns.serial, model=model_options(ns), floor=floor_options(ns),
        site=site_options(ns), json=ns.json,
    )  # fmt: skip


# ---------------------------------------------------------------------------- the archive

#: the archive a command uses when none is given (host.archive.store.archive_url), in the
#: same words everywhere (written out: the store imports SQLAlchemy, which help need not)
ARCHIVE_DEFAULT = (
    "$IMU_BENCH_ARCHIVE, else ~/.local/share/imu-bench/archive.sqlite, under $XDG_DATA_HOME "
    "when set"
)


def add_archive_option(p: argparse.ArgumentParser, lead: str) -> None:
    """--archive URL, its help after ``lead``."""
    p.add_argument(
        "--archive", metavar="URL",
        help=f"{lead}: an SQLite file or postgresql://user@host/db (default {ARCHIVE_DEFAULT})",
    )  # fmt: skip


# ---------------------------------------------------------------------------- values


def positive(text: str) -> float:
    """A number above 0 (argparse's ``type``)."""
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not v > 0:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return v
