"""Errors are types, not texts (host/errors.py): code reacts to a kind of problem by its class,
never by searching the message."""

from __future__ import annotations

import ast
import errno
import os
from pathlib import Path

import pytest

from host.board.link import open_port
from host.errors import UserError

HOST = Path(__file__).resolve().parents[2] / "host"


def _text_filters(tree: ast.AST) -> list[int]:
    """Lines that test an exception's message: ``str(exc).startswith(...)``, ``... in str(exc)``
    (``exc`` bound by an ``except`` clause)."""
    names = {h.name for h in ast.walk(tree) if isinstance(h, ast.ExceptHandler) and h.name}
    hits: list[int] = []

    def is_str_of_exc(node: ast.AST) -> bool:
        return (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Name)
            and node.func.id == "str"
            and len(node.args) == 1
            and isinstance(node.args[0], ast.Name)
            and node.args[0].id in names
        )

    for node in ast.walk(tree):
        if isinstance(node, ast.Compare) and any(
            isinstance(op, (ast.In, ast.NotIn, ast.Eq, ast.NotEq)) for op in node.ops
        ):
            if any(is_str_of_exc(x) for x in [node.left, *node.comparators]):
                hits.append(node.lineno)
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr in ("startswith", "endswith", "find", "count")
            and is_str_of_exc(node.func.value)
        ):
            hits.append(node.lineno)
    return hits


def test_the_scanner_finds_a_text_filter() -> None:
    src = "try:\n    f()\nexcept E as exc:\n    if str(exc).startswith('a') or 'b' in str(exc):\n"
    src += "        pass\n"
    assert _text_filters(ast.parse(src)) == [4, 4]


@pytest.mark.slow
def test_no_module_filters_errors_by_their_message() -> None:
    found = {}
    for path in sorted(HOST.rglob("*.py")):
        hits = _text_filters(ast.parse(path.read_text(encoding="utf-8")))
        if hits:
            found[path.relative_to(HOST).as_posix()] = len(hits)
    assert found == {}


@pytest.mark.parametrize(
    ("url", "named"),
    [
        ("sim://?fault=dance", "sim:// URL: unknown fault 'dance'"),
        ("sim://?nonsense=1", "sim:// URL: unknown option(s) nonsense"),
    ],
)
def test_a_bad_sim_option_is_told_apart_by_its_type(url: str, named: str) -> None:
    """The bad option is named without the cable/port advice (which would mislead)."""
    with pytest.raises(UserError) as ei:
        open_port(url)
    text = str(ei.value)
    assert text.startswith(f"cannot open {url!r}: {named}")
    assert "USB cable" not in text


def test_a_missing_device_gets_the_cable_advice() -> None:
    with pytest.raises(UserError, match="check the USB cable"):
        open_port("/dev/ttyNOSUCH_stages")


@pytest.mark.parametrize(
    ("code", "says", "not_says"),
    [
        (errno.ENOSPC, "the disk is full; the file is unchanged (free some space", "create"),
        (errno.ENOENT, "no such directory; the file is unchanged (create the directory", "space"),
        (errno.EACCES, "permission denied; the file is unchanged (choose a directory you", "space"),
    ],
)
def test_write_error_advice_fits_its_cause(code: int, says: str, not_says: str) -> None:
    """A missing directory was told to 'free some space'; each cause now gets its own advice."""
    from host.errors import write_error

    msg = str(write_error("/x/S1_result.txt", OSError(code, os.strerror(code))))
    assert msg.startswith("cannot write /x/S1_result.txt: ") and says in msg, msg
    assert not_says not in msg, msg
