"""The bench file: what a laboratory writes once about itself and its bench (TOML, data only).

A certificate (ISO/IEC 17025 §7.8) names the laboratory, the bench and the state of its
references; none of that is in the records. The lab writes it once in a small TOML file
(``docs/bench-file.md``; an example in ``examples/bench.toml``) and ``calibrate --bench-file
FILE`` reads it (else ``$IMU_BENCH_FILE``, else ``$XDG_CONFIG_HOME/imu-bench/bench.toml`` when
that file exists: :func:`find_bench_file`). The file is read with :mod:`tomllib` (it never runs
code) and checked on load: an unknown table or key, a missing one, a value of the wrong kind
or out of range is one line naming the file, the key and what to write (:class:`BenchFileError`).

Format 1::

    format = "imu-bench bench"
    version = 1
    [laboratory]  name, address
    [bench]       id (the bench name in every record and the archive)
    [signatory]   name, role (optional)
    [plate]       level_mrad, checked (a date), by (the reference the check was made with)
    [cube]        squareness_mrad, checked, by
    [site]        latitude_deg, height_m, source, checked (optional)
"""

from __future__ import annotations

import datetime as dt
import math
import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from host.errors import InputError

FORMAT = "imu-bench bench"
VERSION = 1
#: where ``calibrate`` looks for a bench file when none is given
BENCH_FILE_ENV = "IMU_BENCH_FILE"
CONFIG_NAME = "imu-bench/bench.toml"
MAX_BYTES = 64 * 1024
MAX_TEXT = 200

#: table -> (required keys, optional keys)
_TABLES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "laboratory": (("name", "address"), ()),
    "bench": (("id",), ()),
    "signatory": (("name",), ("role",)),
    "plate": (("level_mrad", "checked", "by"), ()),
    "cube": (("squareness_mrad", "checked", "by"), ()),
    "site": (("latitude_deg", "height_m", "source"), ("checked",)),
}


class BenchFileError(InputError):
    """A bench file that cannot be read or breaks its format: one line naming the file and
    the key."""


@dataclass(frozen=True)
class Check:
    """One reference of the bench and its last check: ``value`` in ``unit`` (mrad), when
    (``checked``, ISO date) and with what (``by``)."""

    value: float
    unit: str
    checked: str
    by: str


@dataclass(frozen=True)
class Site:
    """Where the bench stands: latitude (degrees) and height (m) for Helmert's formula;
    ``source``: where they come from; ``checked``: when ('' not said)."""

    source: str
    latitude_deg: float
    height_m: float
    checked: str = ""


@dataclass(frozen=True)
class BenchFile:
    """A laboratory's bench file as read (``path``: the file it came from)."""

    path: str
    lab_name: str
    lab_address: str
    bench_id: str
    signatory: str
    signatory_role: str
    plate: Check
    cube: Check
    site: Site


def find_bench_file(given: str | None) -> Path | None:
    """The bench file to use: ``given`` (``--bench-file``), else ``$IMU_BENCH_FILE``, else
    ``$XDG_CONFIG_HOME/imu-bench/bench.toml`` (``~/.config/…``) when that file exists; None
    when there is none. ``--bench-file none`` uses none."""
    if given is not None:
        return None if given.lower() == "none" else Path(given)
    env = os.environ.get(BENCH_FILE_ENV)
    if env:
        return Path(env)
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    own = Path(base) / CONFIG_NAME
    return own if own.is_file() else None


def load_bench_file(path: str | os.PathLike[str]) -> BenchFile:
    """Read and check the bench file at ``path``; BenchFileError (one line) when it cannot be
    read or breaks format 1."""
    p = Path(path)
    doc = _parse(p)
    where = str(p)
    if doc.get("format") != FORMAT or doc.get("version") != VERSION:
        raise BenchFileError(
            f'{where}: not a bench file of this program (it starts with format = "{FORMAT}" '
            f"and version = {VERSION}; see docs/bench-file.md)"
        )
    extra = sorted(set(doc) - {"format", "version", *_TABLES})
    if extra:
        raise BenchFileError(f"{where}: unknown table or key {extra[0]!r} (known: "
                             f"{', '.join(_TABLES)})")  # fmt: skip
    t = {name: _table(doc, name, where) for name in _TABLES}
    return BenchFile(
        path=where,
        lab_name=_text(t["laboratory"], "laboratory", "name", where),
        lab_address=_text(t["laboratory"], "laboratory", "address", where),
        bench_id=_text(t["bench"], "bench", "id", where),
        signatory=_text(t["signatory"], "signatory", "name", where),
        signatory_role=_text(t["signatory"], "signatory", "role", where, ""),
        plate=_check(t["plate"], "plate", "level_mrad", where),
        cube=_check(t["cube"], "cube", "squareness_mrad", where),
        site=_site(t["site"], where),
    )


def _parse(p: Path) -> dict[str, Any]:
    """The TOML document of ``p``, or BenchFileError naming what is wrong."""
    try:
        with p.open("rb") as f:
            raw = f.read(MAX_BYTES + 1)
    except OSError as exc:
        raise BenchFileError(f"{p}: cannot read the bench file ({exc.strerror or exc})") from None
    if len(raw) > MAX_BYTES:
        raise BenchFileError(f"{p}: over {MAX_BYTES // 1024} KiB: not a bench file")
    try:
        return tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise BenchFileError(f"{p}: not UTF-8 text: a bench file is TOML") from None
    except tomllib.TOMLDecodeError as exc:
        raise BenchFileError(f"{p}: not TOML ({exc}); see docs/bench-file.md") from None


def _table(doc: Mapping[str, Any], name: str, where: str) -> Mapping[str, Any]:
    """The table ``[name]`` with its required keys and no unknown ones."""
    required, optional = _TABLES[name]
    t = doc.get(name)
    if not isinstance(t, dict):
        raise BenchFileError(f"{where}: no [{name}] table (it needs {', '.join(required)})")
    missing = [k for k in required if k not in t]
    if missing:
        raise BenchFileError(f"{where}: [{name}] has no {missing[0]!r}")
    unknown = sorted(set(t) - set(required) - set(optional))
    if unknown:
        known = ", ".join((*required, *optional))
        raise BenchFileError(f"{where}: [{name}] {unknown[0]!r} is no key of it (known: {known})")
    return t


def _text(t: Mapping[str, Any], table: str, key: str, where: str, default: str | None = None,
          ) -> str:  # fmt: skip
    """A one-line printable text of 1 to MAX_TEXT characters."""
    v = t.get(key, default)
    if v == default and default is not None:
        return default
    if not isinstance(v, str) or not v.strip():
        raise BenchFileError(f"{where}: [{table}] {key}: give a text in quotes, got {v!r}")
    if len(v) > MAX_TEXT or any(not c.isprintable() for c in v):
        raise BenchFileError(
            f"{where}: [{table}] {key}: give one line of printable text, at most {MAX_TEXT} "
            "characters"
        )
    return v.strip()


def _number(t: Mapping[str, Any], table: str, key: str, where: str, lo: float, hi: float,
            ) -> float:  # fmt: skip
    """A number within [lo, hi]."""
    v = t[key]
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise BenchFileError(f"{where}: [{table}] {key}: give a number, got {v!r}")
    if not lo <= v <= hi:
        raise BenchFileError(f"{where}: [{table}] {key} = {v:g} is not within {lo:g} to {hi:g}")
    return float(v)


def _date(t: Mapping[str, Any], table: str, key: str, where: str) -> str:
    """A date (TOML date or 'YYYY-MM-DD'), ISO; not in the future."""
    v = t[key]
    if isinstance(v, str):
        try:
            v = dt.date.fromisoformat(v)
        except ValueError:
            v = None
    if isinstance(v, dt.datetime):
        v = v.date()
    if not isinstance(v, dt.date):
        raise BenchFileError(f"{where}: [{table}] {key}: give a date as 2026-11-20, got "
                             f"{t[key]!r}")  # fmt: skip
    if v > dt.date.today():
        raise BenchFileError(f"{where}: [{table}] {key} = {v.isoformat()} is in the future")
    return v.isoformat()


def _check(t: Mapping[str, Any], table: str, key: str, where: str) -> Check:
    """A reference's last check: its value (mrad, 0 to 100), date and how."""
    return Check(value=_number(t, table, key, where, 0.0, 100.0), unit="mrad",
                 checked=_date(t, table, "checked", where),
                 by=_text(t, table, "by", where))  # fmt: skip


def _site(t: Mapping[str, Any], where: str) -> Site:
    """The site: its latitude and height (Helmert's formula gives g from them)."""
    source = _text(t, "site", "source", where)
    checked = _date(t, "site", "checked", where) if "checked" in t else ""
    for key in ("latitude_deg", "height_m"):
        if key not in t:
            raise BenchFileError(f"{where}: [site] has no {key!r} (give latitude_deg and height_m)")
    return Site(source=source, latitude_deg=_number(t, "site", "latitude_deg", where, -90, 90),
                height_m=_number(t, "site", "height_m", where, -500, 9000),
                checked=checked)  # fmt: skip
