"""The dialogue's options (host/dialogue/options.py): read from the ``calibrate`` arguments,
checked before the board is opened, and the operator's answers parsed."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.dialogue import options
from host.errors import UserError
from host.session.records import turn_window_s
from tests.host.dialogue.flat_options import flat, flat_options, options_of


def test_options_from_args() -> None:
    o = options_of("python3 -m host calibrate --port sim:// --serial A-1 --out d "
                   "--static-seconds 5 --turns 3 --warmup 0 --latitude 50 --height 10 --yes "
                   "--resume --ready-seconds 1.5")  # fmt: skip
    f = flat(o)
    assert (f.out, f.turns, f.warmup_s, f.resume, f.ready_s) == (Path("d"), 3, 0.0, True, 1.5)
    o.check()
    for bad in ("", "x" * 13, "a b", "é"):
        with pytest.raises(ValueError):
            options.parse_serial(bad)


def test_turn_windows() -> None:
    assert [turn_window_s(n) for n in (1, 2, 3, 4, 5)] == [7.0, 12.0, 15.0, 19.0, 23.0]
    with pytest.raises(ValueError):
        options.parse_turns("0")
    assert options.parse_turns("4") == 4


def test_the_latitude_is_checked_before_the_board() -> None:
    with pytest.raises(UserError, match="latitude"):
        flat_options(serial="A", latitude_deg=123.0).check()


def test_redo_names_are_checked() -> None:
    with pytest.raises(UserError, match="--redo x_side: not a record name; use one of x_up"):
        flat_options(serial="A", redo=("x_side",)).check()


@settings(max_examples=40, deadline=None)
@given(
    axis=st.sampled_from("xyz"),
    way=st.sampled_from(["up", "dn", "ccw", "cw"]),
    rep=st.none() | st.from_regex(r"[0-9A-Za-z]{1,4}", fullmatch=True),
    junk=st.text(min_size=1, max_size=12),
)
def test_redo_takes_every_record_name_a_session_writes_and_nothing_else(
    axis: str, way: str, rep: str | None, junk: str
) -> None:
    """The six faces, the six turns and their repeats (``x_ccw_2``, the closing ``x_up_2``,
    the planner's ``y_up_3``) are names ``--redo`` measures again; anything else is refused
    with the names to use."""
    name = f"{axis}_{way}" + (f"_{rep}" if rep else "")
    flat_options(serial="A", redo=(name,)).check()
    if not re.fullmatch(r"[xyz]_(up|dn|ccw|cw)(_[0-9A-Za-z]+)?", junk):
        with pytest.raises(UserError, match=r"(?s)--redo .*not a record name; use one of x_up"):
            flat_options(serial="A", redo=(junk,)).check()


def test_redo_takes_several_names_comma_separated_or_repeated() -> None:
    o = options_of("python3 -m host calibrate --redo x_up,y_cw --redo z_dn")
    assert o.files.redo == ("x_up", "y_cw", "z_dn")


@pytest.mark.parametrize("opt", ["operator", "bench", "lot"])
def test_a_name_with_a_control_character_is_refused_before_the_board(opt: str) -> None:
    """It would be written into every record's header and the archive (an escape sequence then
    colours or clears the screen of whoever lists the lot)."""
    o = flat_options(serial="A", **{opt: "bench\x1b[2J"})
    with pytest.raises(UserError, match=f"--{opt}: .*control character"):
        o.check()
    flat_options(serial="A", **{opt: "Ana María, bench 3"}).check()
