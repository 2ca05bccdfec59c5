"""The text report's lines: 80 columns, words wrapped, and cut into numbered pages.

A page of ``SERIAL_result.txt`` is at most :data:`PAGE_LINES` lines (A4 at 12 characters
and 8 lines per inch); each page after the first starts with a form feed (the page break a
printer honours) and its header line, the report number with "page i of n"
(:func:`paginate`).
"""

from __future__ import annotations

from collections.abc import Callable

WIDTH = 80
#: lines per page of the text report, its header line included
PAGE_LINES = 80
#: starts every page after the first (a printer's page break)
FORM_FEED = "\f"


def wrap(text: str, first: str, indent: str, keep: tuple[str, ...] = ()) -> list[str]:
    """``text`` in lines ≤ 80 columns, the first after ``first``, the others after ``indent``;
    the phrases in ``keep`` are never broken."""
    lines: list[str] = []
    line = first
    for k in keep:
        text = text.replace(k, k.replace(" ", "\ue000"))
    for word in text.split():
        if line.strip() and len(line) + 1 + len(word) > WIDTH:
            lines.append(line)
            line = indent + word
        else:
            line = f"{line} {word}" if line.strip() else line + word
    if line:
        lines.append(line)
    return [ln.replace("\ue000", " ") for ln in lines]


def cut_pages(lines: list[str], per_page: int, starts: frozenset[int]) -> list[list[str]]:
    """``lines`` cut into pages of at most ``per_page``, each new page at one of ``starts``
    (indices of ``lines`` where a section begins) where one falls in the page's second half,
    so that sections stay whole; else at ``per_page``."""
    pages: list[list[str]] = []
    at = 0
    while len(lines) - at > per_page:
        fits = [i for i in starts if at + per_page // 2 <= i <= at + per_page]
        cut = max(fits) if fits else at + per_page
        pages.append(lines[at:cut])
        at = cut
    return [*pages, lines[at:]] if at < len(lines) else pages


def paginate(
    lines: list[str],
    header: Callable[[int, int], str],
    first_header: int,
    starts: frozenset[int] = frozenset(),
) -> list[str]:
    """``lines`` as pages of at most :data:`PAGE_LINES`, each new page at a section's start
    (``starts``: indices of ``lines``) where one fits: ``header(i, n)`` is the line that says
    "page i of n"; on the first page it replaces line ``first_header``, every later page starts
    with a form feed and it. Returns the lines, the form feeds at the start of the pages'
    first lines."""
    first, *later = cut_pages(lines, PAGE_LINES, starts)
    rest: list[list[str]] = []
    if later:
        at = len(first)
        shifted = frozenset(i - at for i in starts if i > at)
        rest = cut_pages(lines[at:], PAGE_LINES - 1, shifted)
    n = 1 + len(rest)
    first[first_header] = header(1, n)
    out = list(first)
    for i, page in enumerate(rest, 2):
        out += [FORM_FEED + header(i, n), *page]
    return out
