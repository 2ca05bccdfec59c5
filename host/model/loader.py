"""Users' own terms: a Python file of :class:`~host.model.terms.Term` objects (made with
:func:`~host.model.terms.term`) joins the catalogue.

A term file's code runs under a time bound (:data:`TIME_LIMIT_S`, ``--term-timeout``): past
:data:`PROGRESS_S` a line on stderr says which term file is running and for how long, and past
the bound it stops with one line naming the file and the option that raises it (an endless
loop no longer hangs the program). The bound holds for each loading of a file (its loading and
every call of its terms after it), so a program that loads a file again starts afresh.

A term file is code: it runs only when a user names it (``--term-file``, or ``term_files=`` of
:func:`host.calib.applying.apply`), never because a result file mentions it. Its SHA-256
(:func:`term_file_sha256`) travels in the result, so the file given later can be checked to be
the one the calibration used (``load_term_file(..., sha256=...)``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import importlib.util
import os
import posix
import signal
import sys
import threading
import time
from collections.abc import Callable, Collection, Iterator, Mapping
from pathlib import Path
from typing import Any

from host.errors import TermFileMismatch, UserError
from host.model.catalogue import CATALOGUE
from host.model.terms import Term

#: the time a loaded term file's code may run, s (``--term-timeout`` sets it for a command)
TIME_LIMIT_S = 120.0
#: after this long in a term file's code, a progress line every as long, s
PROGRESS_S = 5.0
_active: list[str] = []  # the term file whose code runs now (bounded once, not nested)


@dataclasses.dataclass
class _Budget:
    """The time one loading of the term file ``path`` may still spend in its code: its
    loading and every call of its terms share it, s."""

    path: str
    limit_s: float
    spent_s: float = 0.0


class TermFileTimeout(UserError):
    """A term file's code ran past :data:`TIME_LIMIT_S`."""


@contextlib.contextmanager
def _bounded(budget: _Budget, what: str) -> Iterator[None]:
    """Run user code of ``budget``'s file with progress lines and the time bound it has left
    (main thread only: elsewhere it runs unbounded)."""
    main = threading.current_thread() is threading.main_thread()
    if not main or not hasattr(signal, "setitimer") or _active:
        yield  # elsewhere, or inside user code already bounded: runs as it is
        return
    path, limit = budget.path, budget.limit_s
    _active.append(path)
    start = time.monotonic()
    before = budget.spent_s

    def tick(_signum: int, _frame: object) -> None:
        ran = before + time.monotonic() - start
        if ran > limit:
            raise TermFileTimeout(
                f"{path}: {what} has run {ran:.0f} s (an endless loop?); stopped at the "
                f"bound of {limit:g} s: fix the term, or give --term-timeout S"
            )
        print(f"{path}: {what} running for {ran:.0f} s (bound {limit:g} s, "
              "--term-timeout)", file=sys.stderr, flush=True)  # fmt: skip

    first = max(0.01, min(PROGRESS_S, limit - before))
    old = signal.signal(signal.SIGALRM, tick)
    signal.setitimer(signal.ITIMER_REAL, first, min(PROGRESS_S, max(limit, 0.01)))
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
        budget.spent_s = before + time.monotonic() - start
        _active.clear()


class TermFileExit(UserError):
    """A term file's code tried to end the program (``sys.exit``, ``os._exit``)."""


@contextlib.contextmanager
def _no_exit(path: str, what: str) -> Iterator[None]:
    """Run user code from ``path`` so that its ending the process, however it ends it, is a
    failure: ``sys.exit``/``exit()``/``raise SystemExit`` and ``os._exit`` (which ends the
    process at once, exit status and all, with no result written) raise
    :class:`TermFileExit` naming the file instead."""

    def refuse(how: str) -> TermFileExit:
        return TermFileExit(
            f"{path}: {what} called {how}: a term file may not end the program; nothing was "
            "computed with it (return the term's columns instead)"
        )

    def no_exit(code: int) -> None:
        raise refuse(f"os._exit({code})")

    saved = [(m, m._exit) for m in (os, posix)]
    for m, _ in saved:
        setattr(m, "_exit", no_exit)  # noqa: B010 - restored below
    try:
        yield
    except SystemExit as exc:
        raise refuse(f"sys.exit({exc.code!r})") from None
    finally:
        for m, f in saved:
            setattr(m, "_exit", f)  # noqa: B010


def _guarded(
    budget: _Budget, what: str, fn: Callable[..., Any] | None
) -> Callable[..., Any] | None:
    """``fn`` (a term's user function) run under :func:`_bounded` and :func:`_no_exit`."""
    if fn is None:
        return None

    @functools.wraps(fn)
    def run(*args: Any, **kwargs: Any) -> Any:
        with _no_exit(budget.path, what), _bounded(budget, what):
            return fn(*args, **kwargs)

    return run


def _read(p: Path) -> bytes:
    if not p.is_file():
        what = (
            "is a directory; give the Python file (my_terms.py) in it"
            if p.is_dir()
            else "is not a file; give a Python file"
            if p.exists()
            else "no such term file"
        )
        raise UserError(f"{p}: {what}")
    try:
        return p.read_bytes()
    except OSError as exc:
        raise UserError(f"{p}: cannot read the term file ({exc.strerror or exc})") from exc


def term_file_sha256(path: str | Path) -> str:
    """The SHA-256 of a term file's bytes, hex (what a result stores for each term file)."""
    return hashlib.sha256(_read(Path(path))).hexdigest()


def load_term_file(
    path: str | Path,
    catalogue: Mapping[str, Term] | None = None,
    *,
    sha256: Collection[str] | None = None,
) -> dict[str, Term]:
    """Import a Python file of user terms (module-level :class:`Term` objects, e.g. made with
    :func:`term`) and return the catalogue extended by them. UserError on any failure.

    ``sha256``: the digests (hex) the file may have; a file with another one is refused
    before any of it runs (:class:`~host.errors.TermFileMismatch`). The bytes checked are the
    bytes run."""
    p = Path(path)
    code = _read(p)
    digest = hashlib.sha256(code).hexdigest()
    if sha256 is not None and digest not in sha256:
        known = ", ".join(d[:12] for d in sha256) or "none"
        raise TermFileMismatch(
            f"{p}: this term file (sha256 {digest[:12]}…) is not the one the result was "
            f"calibrated with (sha256 {known}…); give that file, or recalibrate with this one"
        )
    mod_name = f"_imu_bench_terms_{digest[:16]}"
    spec = importlib.util.spec_from_loader(mod_name, loader=None, origin=str(p))
    if spec is None:
        raise UserError(f"{p}: cannot load it as Python")
    module = importlib.util.module_from_spec(spec)
    module.__file__ = str(p)
    sys.modules[mod_name] = module
    budget = _Budget(str(p), TIME_LIMIT_S)
    try:
        with _no_exit(str(p), "loading it"), _bounded(budget, "loading it"):
            exec(compile(code, str(p), "exec"), module.__dict__)  # noqa: S102 - the user named it
    except (TermFileTimeout, TermFileExit):
        raise
    except UserError as exc:
        raise UserError(f"{p}: {exc}") from exc
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - user code: one line for the user
        raise UserError(f"{p}: error in the term file: {type(exc).__name__}: {exc}") from exc
    out = dict(catalogue if catalogue is not None else CATALOGUE)
    found = [v for v in vars(module).values() if isinstance(v, Term)]
    if not found:
        raise UserError(f"{p}: defines no term (decorate a column function with @term(...))")
    for t in found:
        if t.name in out or t.name == "base":  # a user term never replaces a built-in one
            raise UserError(
                f"{p}: term {t.name!r} has the name of a built-in term; give yours another "
                f"name (@term(name=...)); taken: base, {', '.join(out)}"
            )
        code_of: dict[str, Any] = {
            f: _guarded(budget, f"term {t.name}", getattr(t, f)) for f in _USER_CODE
        }
        out[t.name] = dataclasses.replace(t, **code_of)
    return out


#: the Term fields that hold the user's code
_USER_CODE = ("columns", "check", "labels", "value", "record_columns")
