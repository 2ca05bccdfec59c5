"""The layout by stages (issue 14): module sizes, the README table, the tests mirroring the tree."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: above this many lines a module states why it is long (issue 14: "no module is longer than
#: about 600 lines without a reason stated in its docstring")
LONG_MODULE_LINES = 600


def test_every_long_module_states_why_in_its_docstring() -> None:
    import ast

    unexplained = []
    for path in sorted((ROOT / "host").rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        if text.count("\n") <= LONG_MODULE_LINES or path.name == "protocol_gen.py":
            continue
        doc = ast.get_docstring(ast.parse(text)) or ""
        if "\nLength (over 600 lines): " not in doc:
            unexplained.append(f"{path.relative_to(ROOT)} ({text.count(chr(10))} lines)")
    assert unexplained == [], "split these or say why they are long: " + ", ".join(unexplained)


def test_the_layout_table_and_each_package_docstring_name_every_module() -> None:
    """A reader goes from the layout table (docs/layout.md, linked from the README's 'What is
    here') to any stage in one step: each package has a row linking its opening docstring, and
    both name every module in it."""
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
    "test_errors.py",  # host/errors.py
    "test_import_graph.py",
    "test_issue17_sweep.py",  # bad input to every command
    "test_layout.py",
    "test_readme_examples.py",  # the README's examples as written
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
