"""Users' own terms: a Python file of :class:`~host.model.terms.Term` objects (made with
:func:`~host.model.terms.term`) joins the catalogue.

A term file is code: it runs only when a user names it (``--term-file``, or ``term_files=`` of
:func:`host.calib.applying.apply`), never because a result file mentions it. Its SHA-256
(:func:`term_file_sha256`) travels in the result, so the file given later can be checked to be
the one the calibration used (``load_term_file(..., sha256=...)``).
"""

from __future__ import annotations

import hashlib
import importlib.util
import sys
from collections.abc import Collection, Mapping
from pathlib import Path

from host.errors import TermFileMismatch, UserError
from host.model.catalogue import CATALOGUE
from host.model.terms import Term


def _read(p: Path) -> bytes:
    if not p.is_file():
        raise UserError(f"{p}: no such term file")
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
    try:
        exec(compile(code, str(p), "exec"), module.__dict__)  # noqa: S102 - the user named it
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
        out[t.name] = t
    return out
