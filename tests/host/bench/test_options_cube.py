"""``cube=`` and ``slot=`` on sim:// and emu:// URLs, whatever their text (issue 45 item 2): a
whole cube number and a slot 0–7 open; anything else is one line naming the option, through
the parser and through a command (exit 2, never a traceback)."""

from __future__ import annotations

import contextlib
import io
import tempfile
import urllib.parse
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from host.__main__ import main
from host.bench.options import CUBE_MAX, OptionError, parse_sim_options
from host.transports import protocol_emu

SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)

texts = st.one_of(
    st.integers(-3, 12).map(str),
    st.integers(0, 2**40).map(str),
    st.integers(0, 255).map(hex),
    st.text(alphabet="0123456789.-+xea", max_size=6),
)
#: a key's text, or the key left out (None)
maybe = st.one_of(st.none(), texts)


def _valid(cube: str | None, slot: str | None) -> bool:
    """What the URL grammar allows, written apart from the parser: a decimal or 0x number."""

    def number(t: str) -> int | None:
        if t.startswith("0x"):
            return int(t, 16) if t[2:] and all(c in "0123456789abcdef" for c in t[2:]) else None
        return int(t) if t.isdigit() or (t[:1] in "+-" and t[1:].isdigit()) else None

    c = number(cube) if cube is not None else None
    if cube is not None and (c is None or not 0 <= c <= CUBE_MAX):
        return False
    if slot is None:
        return True
    k = number(slot)
    return cube is not None and k is not None and 0 <= k <= 7


def _query(cube: str | None, slot: str | None) -> str:
    pairs = [(k, v) for k, v in (("cube", cube), ("slot", slot)) if v is not None]
    return urllib.parse.urlencode(pairs)


@settings(max_examples=60, **SETTINGS)  # type: ignore[arg-type]
@given(maybe, maybe)
def test_the_parsers_take_good_values_and_name_a_bad_one(
    cube: str | None, slot: str | None
) -> None:
    query = _query(cube, slot)
    opts = urllib.parse.parse_qs(query, keep_blank_values=True)
    try:
        got = parse_sim_options(opts, "max", True)
    except OptionError as exc:
        assert not _valid(cube, slot), (cube, slot, str(exc))
        assert exc.key in ("cube", "slot") and "\n" not in str(exc)
        assert exc.key in str(exc)
    else:
        assert _valid(cube, slot), (cube, slot)
        assert (got.cube is None) == (cube is None) and 0 <= got.slot <= 7
    try:
        protocol_emu.parse_sim_options(f"emu://?{query}")
        assert _valid(cube, slot)
    except ValueError as exc:
        assert not _valid(cube, slot) and str(exc).startswith("emu:// option ")


@settings(max_examples=8, **SETTINGS)  # type: ignore[arg-type]
@given(maybe, maybe)
def test_a_command_given_them_opens_or_says_one_line(cube: str | None, slot: str | None) -> None:
    url = f"sim://?speed=max&{_query(cube, slot)}"
    out, err = io.StringIO(), io.StringIO()
    with tempfile.TemporaryDirectory() as tmp:
        argv = ["capture", "--port", url, "--seconds", "0.05", str(Path(tmp) / "c.cap")]
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            rc = main(argv)
    assert "Traceback" not in err.getvalue()
    errors = [x for x in err.getvalue().splitlines() if x.startswith("error:")]
    if _valid(cube, slot):
        assert rc == 0, (url, err.getvalue())
    else:
        assert rc == 2 and len(errors) == 1, (url, err.getvalue())
        assert "cube" in errors[0] or "slot" in errors[0]
