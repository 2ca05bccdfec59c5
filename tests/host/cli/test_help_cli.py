"""Every command's help: a description and a runnable example, the exit codes said once;
mistakes on the command line are one line naming the problem and the help (issue 27)."""

from __future__ import annotations

import argparse
import contextlib
import io

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host.__main__ import COMMANDS, build_parser, leaf_parser
from tests.host.cli.cli_run import run


def every_command() -> list[list[str]]:
    parser, _ = build_parser()
    found: list[list[str]] = []

    def walk(p: argparse.ArgumentParser, path: list[str]) -> None:
        subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs:
            found.append(path)
        for name, child in subs[0].choices.items() if subs else ():
            walk(child, [*path, name])

    walk(parser, [])
    return [p for p in found if p]


@pytest.mark.parametrize("path", every_command(), ids=" ".join)
def test_every_command_has_a_description_and_a_runnable_example(path: list[str]) -> None:
    rc, out, _ = run([*path, "--help"])
    assert rc == 0
    head, _, rest = out.partition("\n\n")
    assert head.startswith("usage:")
    description = rest.split("\n\n")[0]
    assert len(description.split()) >= 3, out  # words, not the usage again
    examples = out.split("examples:\n", 1)[-1] if "examples:\n" in out else ""
    assert f"python3 -m host {' '.join(path)}" in examples, out
    assert ("exit status:" in out) == (path == ["calibrate"]), out  # said once, at the top


def every_parser() -> list[tuple[str, argparse.ArgumentParser]]:
    """Every parser of the command line, the top one and each command's and subcommand's."""
    parser, _ = build_parser()
    found: list[tuple[str, argparse.ArgumentParser]] = []

    def walk(p: argparse.ArgumentParser) -> None:
        found.append((p.prog, p))
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                for child in a.choices.values():
                    walk(child)

    walk(parser)
    return found


def test_every_option_and_argument_of_every_command_has_help() -> None:
    """Was: a dozen without a word (capture --baud, the archive's filters)."""
    missing = [
        f"{prog} {' '.join(a.option_strings) or a.dest}"
        for prog, p in every_parser()
        for a in p._actions
        if not isinstance(a, argparse._SubParsersAction) and not (a.help or "").strip()
    ]
    assert missing == []


def test_calibrate_and_the_archive_commands_name_the_default_archive_alike() -> None:
    from host.archive.store import ARCHIVE_ENV

    said = []
    for _, p in every_parser():
        for a in p._actions:
            if "--archive" in a.option_strings:
                said.append(" ".join((a.help or "").split("(default ", 1)[1].split()))
    assert len(said) == 1 + 11 and len(set(said)) == 1, said  # calibrate, the 11 actions
    assert f"${ARCHIVE_ENV}" in said[0] and "~/.local/share/imu-bench/archive.sqlite" in said[0]


def example_commands(help_text: str) -> list[str]:
    """The example commands of a help text, each joined from its lines (`` \\`` ends a line
    the command goes on from); what follows one is its description, indented more."""
    lines = help_text.split("examples:\n", 1)[1].split("\n\n", 1)[0].splitlines()
    found: list[str] = []
    going_on = False
    for line in lines:
        if going_on:
            found[-1] = found[-1][:-1] + line.strip()
        elif line.startswith("  python3 -m host "):
            found.append(line.strip())
        else:
            assert line.startswith("      ") and not line.strip().startswith("-"), line
        going_on = found[-1].endswith("\\") if found else False
    return found


@pytest.mark.parametrize("columns", [80, 50])
@pytest.mark.parametrize("path", every_command(), ids=" ".join)
@pytest.mark.slow
def test_help_examples_keep_each_command_whole_and_runnable_as_pasted(
    path: list[str], columns: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Was: re-wrapped at 80 columns, a command broke mid-way and its description spilled into
    the command column (``plan U17/  the next record that buys the most`` / ``precision``).
    Now each command, joined from its lines as a shell joins them, is one the parser reads
    whole, and what is said about it is on lines of its own."""
    import shlex

    monkeypatch.setenv("COLUMNS", str(columns))
    _, out, _ = run([*path, "--help"])
    commands = example_commands(out)
    assert commands, out
    parser, _ = build_parser()
    for command in commands:
        words = shlex.split(command.split(" | ")[0])  # (a pipe into another program)
        assert words[:3] == ["python3", "-m", "host"], command
        with contextlib.redirect_stderr(io.StringIO()) as err:
            try:
                parser.parse_args(words[3:])
            except SystemExit:
                raise AssertionError(f"{command}: {err.getvalue()}") from None
    for line in out.split("examples:\n", 1)[1].splitlines():
        assert len(line) <= columns or " " not in line.strip(), line


def test_help_is_wrapped_at_spaces_only(monkeypatch: pytest.MonkeyPatch) -> None:
    """No word cut at its hyphen ("imu-" / "bench") at 80 columns."""
    monkeypatch.setenv("COLUMNS", "80")
    _, out, _ = run(["archive", "list", "--help"])
    assert "imu-bench" in out.replace("\n", " ").replace("  ", " ") and "imu-\n" not in out


def test_the_exit_codes_are_in_the_top_help() -> None:
    rc, out, _ = run(["--help"])
    assert rc == 0 and "exit status:" in out and "130" in out


def test_demo_help_names_its_demo_once() -> None:
    _, out, _ = run(["demo", "--help"])
    assert out.count("hidden-effect") == out.count("demo hidden-effect") + 1, out


def test_an_option_a_subcommand_lacks_is_answered_by_that_subcommand() -> None:
    rc, out, err = run(["model", "ladder", "DIR", "--plot", "d"])
    assert rc == 2 and out == ""
    see = "(see: python3 -m host model ladder --help)"
    assert err == f"error: unrecognized arguments: --plot d {see}\n"


def test_import_without_serial_is_one_line() -> None:
    rc, _, err = run(["import", "x.csv"])
    assert rc == 2
    assert err.count("\n") == 1 and "--serial" in err and "import --help" in err


def test_leaf_parser_finds_the_subcommand() -> None:
    parser, _ = build_parser()
    args, _ = parser.parse_known_args(["archive", "list"])
    assert leaf_parser(parser, args).prog == "python3 -m host archive list"


tokens = st.sampled_from(
    ["--plot", "--model", "--serial", "--out", "--seconds", "--floor", "--window", "--order",
     "--effect", "--seed", "--alpha", "--k", "--top", "--to", "--axes", "--units", "--columns",
     "--turns", "--latitude", "-x", "--", "", "x", "-1", "nan", "1e999", "a.png", "é", "\x00"]
)  # fmt: skip


@settings(max_examples=150, deadline=None)
@given(st.sampled_from(sorted(COMMANDS)), st.lists(tokens | st.text(max_size=6), max_size=6))
@pytest.mark.slow
def test_any_options_are_parsed_or_refused_in_one_line(command: str, argv: list[str]) -> None:
    """The parse of any words: a namespace, or exit 2 with one line — never a traceback."""
    parser, _ = build_parser()
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            args, extra = parser.parse_known_args([command, *argv])
            if extra:
                leaf_parser(parser, args).error(f"unrecognized arguments: {' '.join(extra)}")
        except SystemExit as exc:
            if exc.code != 0:  # --help exits 0
                assert exc.code == 2
                assert err.getvalue().startswith("error: ") and err.getvalue().count("\n") == 1
