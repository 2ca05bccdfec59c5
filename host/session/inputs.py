"""What comes in from outside, checked in one place: the serial rule and JSON within bounds.

**The serial rule.** A unit's serial number is 1 to 12 characters of ``A-Z a-z 0-9 _ -``: it
starts every file name of a session (``SERIAL_x_up.txt``), so it can hold no path, no space and
no line break. Every way a serial comes in obeys it or is refused with one line naming what
breaks it: the ``--serial`` option and the dialogue's answer (:func:`parse_serial`), the record
files' names and their ``# serial:`` header (:func:`check_serial`, via
:func:`host.session.directory.read_session`), a result JSON
(:func:`host.calib.codec.result_from_json`) and the archive. Where a serial is written (every
export format, the report, HTML),
:func:`written_serial` gives it as it is when it obeys the rule and otherwise as escaped text
of ``A-Z a-z 0-9 _ - \\``, so that no serial is ever more than one line of any file, nor ends a
comment or opens a tag there.

**JSON within bounds.** :func:`load_json` reads a result, thermal or noise file refusing, with
one line, a file over :data:`MAX_JSON_BYTES` or nested deeper than :data:`MAX_JSON_DEPTH` (the
parser would recurse until Python's stack limit: a ``RecursionError`` traceback).
"""

from __future__ import annotations

import json
import re
from typing import Any

import numpy as np

from host.errors import InputError

SERIAL_RE = re.compile(r"[A-Za-z0-9_-]{1,12}")
SERIAL_RULE = "1 to 12 characters: letters, digits, _ or - (it starts every file name)"
#: the characters a written serial may hold; anything else is escaped
_PLAIN = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-")

#: the largest JSON file a command reads (results, thermal and noise files are kilobytes), bytes
MAX_JSON_BYTES = 16 * 2**20
#: the deepest nesting of arrays and objects in a JSON file a command reads (ours: 4)
MAX_JSON_DEPTH = 32


def serial_problem(serial: str) -> str | None:
    """What in ``serial`` breaks the rule, in words ('not allowed: '\\n' ' '; 13 characters'),
    or None when it obeys it."""
    if SERIAL_RE.fullmatch(serial):
        return None
    if not serial:
        return "empty"
    why = []
    bad = sorted({c for c in serial if c not in _PLAIN})
    if bad:
        shown = " ".join(repr(c) for c in bad[:8]) + (" …" if len(bad) > 8 else "")
        why.append(f"not allowed: {shown}")
    if len(serial) > 12:
        why.append(f"{len(serial)} characters")
    return "; ".join(why)


def check_serial(serial: str, where: str = "serial number") -> str:
    """``serial`` itself when it obeys the rule; ValueError naming ``where`` it came from, the
    serial (as typed when printable, else escaped) and what breaks the rule otherwise."""
    why = serial_problem(serial)
    if why is None:
        return serial
    shown = serial if serial.isprintable() and len(serial) <= 29 else written_serial(serial)
    raise ValueError(f"{where} '{shown}' ({why}): use {SERIAL_RULE}")


def parse_serial(text: str) -> str:
    """A typed serial number (the ``--serial`` option, the dialogue's answer): ``text`` less
    surrounding blanks, checked by the rule; ValueError states the rule and what breaks it."""
    s = text.strip()
    if not s:
        raise ValueError(f"the serial number is mandatory: {SERIAL_RULE}")
    return check_serial(s)


def written_serial(serial: str) -> str:
    """``serial`` as a file shows it: itself when it obeys the rule, else each character
    outside ``A-Z a-z 0-9 _ -`` as ``\\xNN``/``\\uNNNN``/``\\UNNNNNNNN`` (a backslash as
    ``\\x5c``) cut to at most 29 characters: one line, no comment end, no markup."""
    if SERIAL_RE.fullmatch(serial):
        return serial
    out: list[str] = []
    for c in serial:
        if sum(map(len, out)) > 16:
            out.append("...")
            break
        n = ord(c)
        if c in _PLAIN:
            out.append(c)
        elif n < 0x100:
            out.append(f"\\x{n:02x}")
        elif n < 0x10000:
            out.append(f"\\u{n:04x}")
        else:
            out.append(f"\\U{n:08x}")
    return "".join(out)


# --------------------------------------------------------------------------- JSON


_JSON_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"', re.DOTALL)


def json_depth(text: str | bytes) -> int:
    """The deepest nesting of ``[``/``{`` in JSON ``text`` (brackets inside strings aside),
    without parsing it."""
    raw = text.encode("utf-8", "surrogatepass") if isinstance(text, str) else text
    a = np.frombuffer(_JSON_STRING.sub(b'""', raw), dtype=np.uint8)
    step = np.isin(a, (0x5B, 0x7B)).astype(np.int64) - np.isin(a, (0x5D, 0x7D))
    return int(np.cumsum(step).max(initial=0))


def load_json(
    text: str | bytes,
    what: str = "",
    *,
    max_bytes: int = MAX_JSON_BYTES,
    max_depth: int = MAX_JSON_DEPTH,
) -> Any:
    """``json.loads(text)`` for a file a user gives (``what``, when given, starts the message):
    InputError, one line, when it is larger than ``max_bytes`` or nested deeper than
    ``max_depth``; ValueError as ``json.loads`` raises it when it is not JSON."""
    size = len(text.encode("utf-8", "surrogatepass") if isinstance(text, str) else text)
    lead = f"{what}: " if what else ""
    if size > max_bytes:
        raise InputError(
            f"{lead}{size / 2**20:.1f} MiB, more than a JSON file this program reads "
            f"({max_bytes >> 20} MiB); give the file the program wrote"
        )
    depth = json_depth(text)
    if depth > max_depth:
        raise InputError(
            f"{lead}JSON nested {depth} deep, more than the {max_depth} this program reads "
            "(its files are nested 4 deep); give the file the program wrote"
        )
    return json.loads(text)
