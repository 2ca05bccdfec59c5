"""The layout by stages (issues 14, 23): no module over 600 lines, the layout table in docs/,
the tests mirroring the tree."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: no module of host/ is longer than this (issue 23), the generated spec table aside
MAX_MODULE_LINES = 600
GENERATED = {"host/wire/protocol_gen.py"}


def module_lines(path: Path) -> int:
    """Lines as ``wc -l`` counts them."""
    return path.read_bytes().count(b"\n")


def test_no_module_is_over_600_lines() -> None:
    too_long = []
    for path in sorted((ROOT / "host").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        n = module_lines(path)
        if n > MAX_MODULE_LINES and rel not in GENERATED:
            too_long.append(f"{rel} ({n} lines)")
    assert too_long == [], f"split these (at most {MAX_MODULE_LINES} lines): " + ", ".join(too_long)


def test_no_command_reads_the_argparse_namespace_past_its_edge() -> None:
    """The options travel as typed objects (host.cli.options): a ``getattr(args, …)`` reads an
    attribute a command's parser may not have (it did: 21 of them, defaults repeated)."""
    found = [
        p.relative_to(ROOT).as_posix()
        for p in sorted((ROOT / "host").rglob("*.py"))
        if "getattr(args" in p.read_text(encoding="utf-8")
    ]
    assert found == []


def test_no_module_excuses_its_length() -> None:
    """The rule is the number: a split module drops the paragraph that said why it was long."""
    excused = [
        p.relative_to(ROOT).as_posix()
        for p in sorted((ROOT / "host").rglob("*.py"))
        if "Length (over 600 lines)" in p.read_text(encoding="utf-8")
    ]
    assert excused == []


def test_the_line_count_is_that_of_wc(tmp_path: Path) -> None:
    """The rule's count: a file of 601 lines is one too many, 600 is allowed."""
    f = tmp_path / "m.py"
    f.write_text("x = 1\n" * 601)
    assert module_lines(f) == 601 > MAX_MODULE_LINES
    f.write_text("x = 1\n" * 600)
    assert module_lines(f) == MAX_MODULE_LINES


def test_the_layout_table_and_each_package_docstring_name_every_module() -> None:
    """A reader goes from the layout table (docs/layout.md, linked from the README) to any
    stage in one step: each package has a row linking its opening docstring, and both name
    every module in it."""
    import ast

    assert "](docs/layout.md)" in (ROOT / "README.md").read_text(encoding="utf-8")
    table = (ROOT / "docs" / "layout.md").read_text(encoding="utf-8")
    for pkg in sorted(p for p in (ROOT / "host").iterdir() if (p / "__init__.py").is_file()):
        modules = sorted(f.stem for f in pkg.glob("*.py") if f.name != "__init__.py")
        link = f"| [`host/{pkg.name}/`](../host/{pkg.name}/__init__.py) |"
        rows = [line for line in table.splitlines() if line.startswith(link)]
        assert len(rows) == 1, f"docs/layout.md: no row {link}"
        doc = ast.get_docstring(ast.parse((pkg / "__init__.py").read_text(encoding="utf-8")))
        assert doc, f"host/{pkg.name}/__init__.py has no docstring"
        for m in modules:
            assert f"`{m}.py`" in rows[0], f"docs/layout.md row of host/{pkg.name}/ lacks {m}.py"
            assert f"``{m}``" in doc, f"host/{pkg.name}/__init__.py docstring lacks {m}"


#: tests about the whole package, not one stage (they stay in tests/host/)
CROSS_CUTTING = {
    "test_bad_input.py",
    "test_bad_records.py",
    "test_doc_links.py",  # every link of the README and docs/
    "test_errors.py",  # host/errors.py
    "test_main.py",  # host/__main__.py
    "test_import_graph.py",
    "test_issue17_sweep.py",  # bad input to every command
    "test_layout.py",
    "test_readme_examples.py",  # the examples of the README and docs/ as written
}


def test_the_tests_mirror_the_source_tree() -> None:
    """tests/host/<stage>/test_<module>….py for host/<stage>/<module>.py; only tests about the
    whole package stay in tests/host/."""
    tests = ROOT / "tests" / "host"
    assert {p.name for p in tests.glob("test_*.py")} == CROSS_CUTTING
    for path in sorted(tests.glob("*/test_*.py")):
        stage = ROOT / "host" / path.parent.name
        assert (stage / "__init__.py").is_file(), f"{path}: no package host/{stage.name}/"
        modules = {m.stem for m in stage.glob("*.py")}
        name = path.stem.removeprefix("test_")
        # a module of the stage, or (cli) a test across its commands
        assert any(name == m or name.startswith(m + "_") for m in modules) or (
            stage.name == "cli" and (name.endswith("cli") or name == "cli_properties")
        ), f"{path.relative_to(ROOT)} tests no module of host/{stage.name}/"


#: the start of a path that names one machine's disk: a home, a work or mount root, a drive
MACHINE_PATH = re.compile(r"(?<![\w.~-])(?:/(?:home|Users|root|work|mnt|media|srv)/|[A-Z]:\\\\)\w")


def machine_paths(root: Path) -> list[str]:
    """``file:line path`` for each absolute path of one machine in docs/ and tests/ (and the
    README): the project is read and run from any clone, its shared data as ``../shared/…``."""
    here = str(ROOT.parent)  # this clone's own place, whatever it is
    files = [root / "README.md", *sorted((root / "docs").rglob("*.md"))]
    files += sorted(p for p in (root / "tests").rglob("*") if p.suffix in (".py", ".md"))
    bad = []
    for path in files:
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if MACHINE_PATH.search(line) or (len(here) > 1 and here + "/" in line):
                bad.append(f"{path.relative_to(root).as_posix()}:{n} {line.strip()[:80]}")
    return bad


def test_no_doc_or_test_names_one_machines_path() -> None:
    assert machine_paths(ROOT) == []


def test_the_path_check_sees_a_machines_path(tmp_path: Path) -> None:
    """The check itself: a home directory, a work root and a drive letter are found; the
    shared data as ``../shared``, a temporary directory and a serial device are not."""
    (tmp_path / "docs").mkdir()
    (tmp_path / "tests").mkdir()
    (tmp_path / "README.md").write_text("python3 -m host calibrate --from-dir ../shared/data/x\n")
    (tmp_path / "docs" / "a.md").write_text(
        "--out /tmp/demo --port /dev/ttyACM0\nsee /" + "home/alice/imu\n"
    )
    (tmp_path / "tests" / "test_b.py").write_text(
        'DATA = Path("/' + 'work/shared/data")\nWIN = "C:' + '\\\\data\\\\x"\n'
    )
    got = [line.split(" ", 1)[0] for line in machine_paths(tmp_path)]
    assert got == ["docs/a.md:2", "tests/test_b.py:1", "tests/test_b.py:2"]


#: the command as the README does not write it (split so that this file does not hold it)
OTHER_SPELLING = "python" + " -m host"


def other_spellings(root: Path) -> list[str]:
    """``file:line`` for each :data:`OTHER_SPELLING` in the code, docs and tests: the command
    is written one way everywhere, ``python3 -m host`` as the README writes it (issue 42)."""
    files = [root / "README.md", *sorted((root / "docs").rglob("*.md"))]
    for top in ("host", "tests", "benchmarks"):
        files += sorted(p for p in (root / top).rglob("*") if p.suffix in (".py", ".md"))
    return [
        f"{path.relative_to(root).as_posix()}:{n}"
        for path in files
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if re.search(re.escape(OTHER_SPELLING) + r"\b", line)
    ]


def test_the_command_is_written_as_the_readme_writes_it() -> None:
    assert other_spellings(ROOT) == []


def test_the_spelling_check_sees_the_other_spelling(tmp_path: Path) -> None:
    """The check itself: the other spelling in a docstring and a doc is found; the README's
    ``python3 -m host`` and another module run with ``python -m`` are not."""
    for d in ("docs", "host", "tests", "benchmarks"):
        (tmp_path / d).mkdir()
    (tmp_path / "README.md").write_text("python3 -m host calibrate\npython -m pytest -q\n")
    (tmp_path / "docs" / "a.md").write_text("run:\n\n    " + OTHER_SPELLING + " noise F\n")
    (tmp_path / "host" / "m.py").write_text('"""Options of ``' + OTHER_SPELLING + ' import``."""\n')
    (tmp_path / "tests" / "test_c.py").write_text('CMD = "python3 -m host model terms"\n')
    assert other_spellings(tmp_path) == ["docs/a.md:3", "host/m.py:1"]


# --------------------------------------------------------------------------- function length

#: no function of host/ is longer than this (issue 42): a long function is a sequence of named
#: steps, each a function of its own; the generated spec table aside
MAX_FUNCTION_LINES = 60

#: functions still over the bound, by ``path:Qualified.name``, each to be split by the engineer
#: of its package; the list only shrinks (a listed function that is no longer long fails too)
LONG_FUNCTIONS: set[str] = set()


def long_functions(path: Path, rel: str) -> dict[str, int]:
    """``rel:Qualified.name`` -> lines (``def`` line to the last, decorators aside) of every
    function of ``path`` over :data:`MAX_FUNCTION_LINES`, nested ones and methods too."""
    import ast

    out: dict[str, int] = {}

    def walk(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                name = prefix + child.name
                n = (child.end_lineno or child.lineno) - child.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    out[f"{rel}:{name}"] = n
                walk(child, name + ".")
            elif isinstance(child, ast.ClassDef):
                walk(child, prefix + child.name + ".")
            else:
                walk(child, prefix)

    walk(ast.parse(path.read_text(encoding="utf-8"), rel), "")
    return out


def all_long_functions() -> dict[str, int]:
    out: dict[str, int] = {}
    for path in sorted((ROOT / "host").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        if rel not in GENERATED:
            out.update(long_functions(path, rel))
    return out


def test_no_function_is_over_60_lines() -> None:
    too_long = sorted(f"{k} ({n} lines)" for k, n in all_long_functions().items()
                      if k not in LONG_FUNCTIONS)  # fmt: skip
    assert too_long == [], (
        f"split these into named steps (at most {MAX_FUNCTION_LINES} lines): " + ", ".join(too_long)
    )


def test_the_list_of_long_functions_is_still_true() -> None:
    """A function split (or gone) leaves :data:`LONG_FUNCTIONS`: the list only shrinks."""
    assert sorted(set(LONG_FUNCTIONS) - set(all_long_functions())) == []


def test_the_function_length_is_counted_from_def_to_its_last_line(tmp_path: Path) -> None:
    """The rule's count: 61 lines is one too many, 60 allowed; methods and nested functions
    are counted by their own lines and named by their class and outer function."""
    body, deeper = "    x = 1\n", "        x = 1\n"
    f = tmp_path / "m.py"
    f.write_text(
        "def ok():\n" + body * 59
        + "def long():\n" + body * 60
        + "class C:\n    def m(self):\n" + deeper * 60
        + "def outer():\n    def inner():\n" + deeper * 60 + "    return inner\n"
    )  # fmt: skip
    got = long_functions(f, "m.py")
    assert got == {"m.py:long": 61, "m.py:C.m": 61, "m.py:outer": 63, "m.py:outer.inner": 61}
