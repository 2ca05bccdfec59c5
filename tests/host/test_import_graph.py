"""The import graph of host/ (walked from the source, not imported): no circles, and no arrow
from a library module to a command module (host.cli.*, host.__main__), so that the data flows
one way and the library can be used without the command line (issue 14)."""

from __future__ import annotations

import ast
import functools
import io
import re
import tokenize
from pathlib import Path

import pytest

HOST = Path(__file__).resolve().parents[2] / "host"

#: arrows still to remove, each with the reason it is here; the list only shrinks
KNOWN: dict[tuple[str, str], str] = {}


def module_name(path: Path) -> str:
    rel = path.relative_to(HOST.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(HOST.rglob("*.py"))}


@functools.cache
def parsed(path: Path) -> ast.Module:
    """A source file's tree, parsed once per run (the tests only read it)."""
    return ast.parse(path.read_text(encoding="utf-8"), str(path))


@functools.cache
def imported_names(path: Path) -> tuple[str, ...]:
    """Every dotted name ``path`` imports, at any depth of the code (lazy imports count);
    ``from host.wire import frames`` gives host.wire.frames and host.wire. Walked once per
    run: the tree walk is what the graph tests spend their time on."""
    out: list[str] = []
    for node in ast.walk(parsed(path)):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out += [f"{node.module}.{a.name}" for a in node.names] + [node.module]
    return tuple(out)


def imports_of(path: Path, known: set[str]) -> set[str]:
    """Every host module ``path`` imports, at any depth of the code (lazy imports count)."""
    out: set[str] = set()
    for name in imported_names(path):
        while name and name not in known:
            name = name.rpartition(".")[0]
        if name:
            out.add(name)
    return out


def graph() -> dict[str, set[str]]:
    mods = modules()
    known = set(mods)
    return {m: imports_of(p, known) - {m} for m, p in mods.items()}


def circles(g: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(g.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(g):
        if v not in index:
            visit(v)
    return out


def package_of(m: str) -> str:
    """``host.calib.result`` -> ``host.calib``; a module of host/ itself is its own package."""
    parts = m.split(".")
    if len(parts) > 1 and (HOST / parts[1] / "__init__.py").is_file():
        return ".".join(parts[:2])
    return m


def package_graph(g: dict[str, set[str]]) -> dict[str, set[str]]:
    out: dict[str, set[str]] = {}
    for m, ts in g.items():
        a = package_of(m)
        out.setdefault(a, set()).update(b for b in map(package_of, ts) if b != a)
    return out


def test_the_package_graph_sees_a_package_loop() -> None:
    g = {
        "host.wire.frames": {"host.timing.segments"},
        "host.timing.clock": {"host.wire.protocol_gen", "host.timing.segments"},
        "host.timing.segments": set(),
        "host.wire.protocol_gen": set(),
    }
    pg = package_graph(g)
    assert pg == {"host.wire": {"host.timing"}, "host.timing": {"host.wire"}}
    assert circles(pg) == [["host.timing", "host.wire"]]


def test_no_package_imports_a_package_that_imports_it_back() -> None:
    """Packages import downward only: no loop between packages, directly or through others."""
    assert circles(package_graph(graph())) == []


def is_command(m: str) -> bool:
    return m == "host.__main__" or m == "host.cli" or m.startswith("host.cli.")


def test_the_walk_sees_the_known_arrows() -> None:
    """The walker itself: arrows we know are there, top-level and lazy, are found."""
    g = graph()
    assert "host.wire.frames" in g["host.board.link"]  # top level
    assert "host.wire.protocol_gen" in g["host.wire.frames"]  # from host.wire import X as Y
    assert "host.wire.capture" in g["host.wire.stream"]  # inside a function
    assert "host.bench.emulator" in g["host.transports.protocol_emu"]


def test_circles_finds_a_circle_and_nothing_else() -> None:
    g = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert circles(g) == [["a", "b", "c"]]
    assert circles({"a": {"b"}, "b": set()}) == []


def test_no_import_circles() -> None:
    g = graph()
    for edge in KNOWN:
        g[edge[0]].discard(edge[1])
    assert circles(g) == []


#: the port-to-samples packages in their order: each imports only those before it (issue 23)
PORT_PACKAGES = ("host.wire", "host.timing", "host.bench", "host.transports", "host.board")
#: upward package arrows still to remove; the set only shrinks
KNOWN_UPWARD: set[tuple[str, str]] = set()


def test_the_port_packages_import_downward_only() -> None:
    """No package loops among wire, timing, bench, transports and board: wire never imports
    timing, bench never imports transports or board, transports never imports board."""
    pg = package_graph(graph())
    up = sorted(
        (a, b)
        for i, a in enumerate(PORT_PACKAGES)
        for b in pg.get(a, set())
        if b in PORT_PACKAGES[i + 1 :]
    )
    assert set(up) == KNOWN_UPWARD


def test_no_arrow_from_a_library_module_to_a_command_module() -> None:
    g = graph()
    bad = sorted(
        (m, t)
        for m, ts in g.items()
        if not is_command(m)
        for t in ts
        if is_command(t) and (m, t) not in KNOWN
    )
    assert bad == []


def test_the_known_exceptions_are_still_real() -> None:
    """An exception that no longer exists must leave the list (it only shrinks)."""
    g = graph()
    assert [e for e in KNOWN if e[1] not in g.get(e[0], set())] == []


def test_no_module_imports_the_package_root() -> None:
    """``host/__init__.py`` is the API on top of every stage (its names lead into
    :mod:`host.api`), so a module importing it points upward; the version sits at the bottom,
    in :mod:`host.version`, which imports nothing."""
    g = graph()
    assert sorted(m for m, ts in g.items() if "host" in ts) == []
    assert g["host.version"] == set() and "host.api.functions" in g["host"]


def test_every_module_lives_in_a_stage_package() -> None:
    """host/ holds only the package files; every module is in its stage's subpackage."""
    flat = sorted(p.name for p in HOST.glob("*.py"))
    assert flat == ["__init__.py", "__main__.py", "errors.py", "version.py"], (
        "put a new module in its stage's package (docs/layout.md), not in host/ itself"
    )


def test_every_import_of_a_host_module_names_one_that_exists() -> None:
    """No old names: every ``import host.<module>`` / ``from host.<module> import ...`` in
    host/, lazy ones too, names a module or package of the tree (a moved module leaves no alias
    behind)."""
    known = set(modules())
    missing = []
    for m, path in modules().items():
        for node in ast.walk(parsed(path)):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            missing += [
                f"{m}:{node.lineno} {n}"
                for n in names
                if (n == "host" or n.startswith("host.")) and n not in known
            ]
    assert missing == []


#: the bottom of the data's flow (issue 23): what the records and the model engine may import.
#: The calibration and the workbench sit above both and import them, never the other way.
BELOW: dict[str, set[str]] = {
    "host.session": {"host.errors"},
    "host.model": {"host.errors", "host.wire", "host.session"},
}


def test_the_records_and_the_engine_import_only_what_lies_below_them() -> None:
    pg = package_graph(graph())
    for pkg, allowed in BELOW.items():
        assert pg.get(pkg, set()) <= allowed, (pkg, sorted(pg[pkg] - allowed))


def documented_order() -> list[str]:
    """The packages of docs/layout.md's 'Import order' paragraph, bottom first."""
    import re

    text = (HOST.parent / "docs" / "layout.md").read_text(encoding="utf-8")
    para = text.split("**Import order.**", 1)[1].split("\n\n", 1)[0]
    order = para.split("From the bottom:", 1)[1].split(":", 1)[0]
    return ["host." + name for name in re.findall(r"`(\w+)`", order)]


def test_the_documented_import_order_is_the_codes() -> None:
    """docs/layout.md names every package once, bottom first, and no package imports one named
    after it; calib and workbench stay apart."""
    order = documented_order()
    pg = package_graph(graph())
    packages = {p for p in pg if p not in ("host", "host.__main__")}
    assert sorted(order) == sorted(packages)
    up = sorted(
        f"{a} imports {b}"
        for a, bs in pg.items()
        if a in order
        for b in bs
        if order.index(b) > order.index(a)
    )
    assert up == [], "reorder docs/layout.md or remove the upward import"
    assert "host.workbench" not in pg["host.calib"] and "host.calib" not in pg["host.workbench"]


# --------------------------------------------------------------------------- names in the text

#: a dotted module path in prose: ``host.session.records`` or ``host.board.driver.Board``
DOTTED_REF = re.compile(r"(?<![\w./-])host(?:\.[A-Za-z_]\w*)+")
#: a file path in prose: ``host/dialogue/flow.py``
PATH_REF = re.compile(r"(?<![\w./-])host/[\w/]+\.py\b")


def top_level_names(path: Path) -> set[str]:
    """The names a module defines or imports at its top level (also those it declares for
    type checkers under ``if TYPE_CHECKING:``, as host/__init__.py its lazily imported API)."""
    names: set[str] = set()
    body = list(parsed(path).body)  # a copy: the shared tree stays as parsed
    for node in list(body):
        if isinstance(node, ast.If) and ast.unparse(node.test) in (
            "TYPE_CHECKING",
            "typing.TYPE_CHECKING",
        ):
            body += node.body
    for node in body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            names.add(node.name)
        elif isinstance(node, ast.Assign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names |= {n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)}
        elif isinstance(node, ast.Import | ast.ImportFrom):
            names |= {(a.asname or a.name).split(".")[0] for a in node.names}
    return names


def dotted_ref_exists(ref: str, mods: dict[str, Path]) -> bool:
    """``ref`` is a module of the tree, or a module followed by a name it defines (the first
    name after the module is checked; ``Board.physical`` is taken as ``Board``)."""
    parts = ref.rstrip(".").split(".")
    for k in range(len(parts), 0, -1):
        module = ".".join(parts[:k])
        if module in mods:
            return k == len(parts) or parts[k] in top_level_names(mods[module])
    return False


def prose_of(path: Path) -> list[tuple[int, str]]:
    """Every docstring (and other bare string statement) and every comment, with its line."""
    src = path.read_text(encoding="utf-8")
    out = [
        (node.lineno, node.value.value)
        for node in ast.walk(ast.parse(src, str(path)))
        if isinstance(node, ast.Expr)
        and isinstance(node.value, ast.Constant)
        and isinstance(node.value.value, str)
    ]
    tokens = tokenize.generate_tokens(io.StringIO(src).readline)
    out += [(t.start[0], t.string) for t in tokens if t.type == tokenize.COMMENT]
    return out


def dangling_references(paths: list[Path], mods: dict[str, Path]) -> list[str]:
    """``file:line name`` for each module path in the prose of ``paths`` that does not exist."""
    root = HOST.parent
    bad = []
    for path in paths:
        where = path.relative_to(root) if path.is_relative_to(root) else path
        for line, text in prose_of(path):
            bad += [
                f"{where}:{line} {ref}"
                for ref in DOTTED_REF.findall(text)
                if not dotted_ref_exists(ref, mods)
            ]
            missing = [ref for ref in PATH_REF.findall(text) if not (root / ref).is_file()]
            bad += [f"{where}:{line} {ref}" for ref in missing]
    return bad


def test_the_reference_check_tells_a_moved_module_from_a_real_one(tmp_path: Path) -> None:
    mods = modules()
    assert dotted_ref_exists("host.session.records.Record", mods)
    assert dotted_ref_exists("host.board.driver", mods)
    assert dotted_ref_exists("host.dialogue.flow.run_dialogue", mods)
    assert not dotted_ref_exists("host.calibration", mods)  # an old flat name
    assert not dotted_ref_exists("host.dialogue.live", mods)  # a module split away
    assert not dotted_ref_exists("host.dialogue.flow.run_live_session", mods)  # an old alias
    probe = tmp_path / "probe.py"
    probe.write_text(
        '"""Uses :func:`host.records.read_session` and host/dialogue/live.py."""\n'
        "# see host.dialogue.flow and host/dialogue/flow.py\n"
    )
    got = [r.split(" ", 1)[1] for r in dangling_references([probe], mods)]
    assert got == ["host.records.read_session", "host/dialogue/live.py"]
    assert dangling_references([HOST / "dialogue" / "flow.py"], mods) == []


@pytest.mark.slow
def test_every_module_named_in_a_docstring_or_comment_exists() -> None:
    """Docstrings and comments of host/, tests/ and benchmarks/ name modules by their real
    path (``host.session.records``, ``host/board/driver.py``): a module that moved or split
    leaves no reference to its old place behind."""
    root = HOST.parent
    paths = [p for d in ("host", "tests", "benchmarks") for p in sorted((root / d).rglob("*.py"))]
    assert dangling_references(paths, modules()) == []
