"""Every relative link and ``#anchor`` in the README, the pages of docs/ and the firmware's and
protocol's READMEs leads somewhere: a file that exists, a heading that is there (issue 23: the
README is split into pages, and a moved section must not leave a dead link behind)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def pages() -> list[Path]:
    return [
        ROOT / "README.md",
        *sorted((ROOT / "docs").glob("*.md")),
        *sorted((ROOT / "firmware").rglob("README.md")),
        *sorted((ROOT / "protocol").glob("*.md")),
    ]


FENCE = re.compile(r"^(```|~~~).*?^\1[^\n]*$", flags=re.S | re.M)


def links(text: str) -> list[str]:
    """Targets of ``[text](target)`` links outside code: fenced blocks are dropped and each
    inline code span becomes one letter (so ``[`host/wire/`](…)`` stays a link, and a link
    written inside backticks is none)."""
    text = re.sub(r"`[^`\n]*`", "x", FENCE.sub("", text))
    return [m.group(1) for m in re.finditer(r"\]\(([^()\s]+)(?:\s+\"[^\"]*\")?\)", text)]


def slug(heading: str) -> str:
    """The anchor GitHub gives a heading: lower case, punctuation dropped, spaces to hyphens."""
    s = heading.strip().lower()
    s = re.sub(r"[^\w\- ]", "", s)
    return s.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    text = FENCE.sub("", path.read_text(encoding="utf-8"))
    seen: dict[str, int] = {}
    out = set()
    for m in re.finditer(r"^#{1,6}\s+(.+?)\s*#*\s*$", text, flags=re.M):
        base = slug(m.group(1))
        n = seen.get(base, 0)
        seen[base] = n + 1
        out.add(base if n == 0 else f"{base}-{n}")
    return out


def broken_links(page: Path, root: Path = ROOT) -> list[str]:
    bad = []
    for target in links(page.read_text(encoding="utf-8")):
        if re.match(r"[a-z][a-z0-9+.-]*:", target):  # https:, mailto: …: not ours to check
            continue
        path, _, anchor = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists():
            bad.append(
                f"{target}: no file {dest.relative_to(root) if dest.is_relative_to(root) else dest}"
            )
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            bad.append(f"{target}: no heading #{anchor} in {dest.relative_to(root)}")
    return bad


def test_slug_is_githubs() -> None:
    assert slug("Out: `python3 -m host export`") == "out-python3--m-host-export"
    assert slug("The virtual bench (`sim://`)") == "the-virtual-bench-sim"
    assert slug("Noise: Allan deviation and how long to record") == (
        "noise-allan-deviation-and-how-long-to-record"
    )
    assert slug("Words") == "words"


def test_the_checker_finds_a_dead_file_and_a_dead_anchor(tmp_path: Path) -> None:
    (tmp_path / "a.md").write_text(
        "# A\n\n## Two words\n\n[ok](b.md) [ok](#two-words) [x](gone.md) [y](b.md#nothing)\n"
        "`[not a link](gone2.md)`\n\n```sh\n[nor](gone3.md)\n```\n[web](https://example.org)\n"
    )
    (tmp_path / "b.md").write_text("# B\n\n## Here\n")
    bad = broken_links(tmp_path / "a.md", root=tmp_path)
    assert [b.split(":")[0] for b in bad] == ["gone.md", "b.md#nothing"]


def test_the_pages_are_found() -> None:
    names = {p.relative_to(ROOT).as_posix() for p in pages()}
    assert {"README.md", "docs/layout.md", "firmware/README.md", "protocol/README.md"} <= names


def test_every_relative_link_and_anchor_resolves() -> None:
    bad = [f"{p.relative_to(ROOT)}: {b}" for p in pages() for b in broken_links(p)]
    assert bad == []


def test_every_docs_page_is_linked_from_the_readme() -> None:
    """A page nobody links to is a page nobody reads."""
    readme = links((ROOT / "README.md").read_text(encoding="utf-8"))
    orphans = [
        p.name for p in sorted((ROOT / "docs").glob("*.md")) if f"docs/{p.name}" not in readme
    ]
    assert orphans == []


#: where a path named in the docs starts (relative to the repository root); build output aside
PATH_ROOTS = ("host/", "tests/", "benchmarks/", "protocol/", "firmware/", ".ci/")
GENERATED_PATHS = ("firmware/build/",)
PATH_IN_CODE = re.compile(
    r"(?<![\w./-])((?:" + "|".join(map(re.escape, PATH_ROOTS)) + r")[\w./-]*\w)"
)


def named_paths(text: str) -> set[str]:
    """Repository paths named in inline code: ``host/wire/frames.py``, ``tests/…::test_x``."""
    out = set()
    for code in re.findall(r"`([^`\n]+)`", FENCE.sub("", text)):
        for m in PATH_IN_CODE.finditer(code):
            path = m.group(1).split("::")[0]
            if not path.startswith(GENERATED_PATHS) and "{" not in code and "*" not in path:
                out.add(path)
    return out


def named_modules(text: str) -> set[str]:
    """Dotted names under ``host.`` in inline code: ``host.wire.bulk.decode_file``."""
    out = set()
    for code in re.findall(r"`([^`\n]+)`", FENCE.sub("", text)):
        out.update(re.findall(r"(?<![\w.])(host(?:\.\w+)+)", code))
    return out


def missing_names(text: str, root: Path = ROOT) -> list[str]:
    """The paths and ``host.`` names a page mentions that the tree does not have."""
    import importlib

    bad = [p for p in sorted(named_paths(text)) if not (root / p).exists()]
    for name in sorted(named_modules(text)):
        parts = name.split(".")
        for k in range(len(parts), 0, -1):
            base = root.joinpath(*parts[:k])
            if base.with_suffix(".py").is_file() or (base / "__init__.py").is_file():
                break
        rest = parts[k:]  # ``host.apply``: a name the package itself gives (import host)
        if rest and not hasattr(importlib.import_module(".".join(parts[:k])), rest[0]):
            bad.append(name)
    return bad


def test_the_name_check_sees_a_moved_module_and_a_lost_name() -> None:
    text = (
        "see `host/wire/frames.py`, `host/nowhere/x.py`, `host.wire.bulk.decode_bulk`, "
        "`host.wire.frames.no_such_thing`, `host.gone.module`, `tests/host/test_layout.py::t`"
    )
    assert missing_names(text) == [
        "host/nowhere/x.py",
        "host.gone.module",
        "host.wire.frames.no_such_thing",
    ]


def test_every_module_and_path_the_docs_name_exists() -> None:
    """A page that names ``host/timing/clock.py`` or ``host.wire.bulk.decode_file`` sends the
    reader to a file that is there and a name it holds (modules move: the pages follow). The
    firmware's pages also name files the user makes (a DMP image), so: the README and docs/."""
    ours = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    bad = [f"{p.relative_to(ROOT)}: {n}" for p in ours for n in missing_names(p.read_text())]
    assert bad == []


def test_the_readme_is_a_five_minute_read() -> None:
    """Issue 23: at most 250 lines, no wall of text (the longest paragraph was 48 lines); the
    rest lives in docs/."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert text.count("\n") <= 250
    prose = "\n".join(ln for ln in FENCE.sub("", text).splitlines() if not ln.startswith("|"))
    paragraphs = [p for p in prose.split("\n\n") if p.strip()]  # tables aside
    longest = max(paragraphs, key=lambda p: p.strip().count("\n"))
    assert longest.strip().count("\n") + 1 <= 16, longest[:200]
