"""Users' own terms: a Python file of :class:`~host.model.terms.Term` objects (made with
:func:`~host.model.terms.term`) joins the catalogue."""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Mapping
from pathlib import Path

from host.errors import UserError
from host.model.catalogue import CATALOGUE
from host.model.terms import Term


def load_term_file(
    path: str | Path, catalogue: Mapping[str, Term] | None = None
) -> dict[str, Term]:
    """Import a Python file of user terms (module-level :class:`Term` objects, e.g. made with
    :func:`term`) and return the catalogue extended by them. UserError on any failure."""
    p = Path(path)
    if not p.is_file():
        raise UserError(f"{p}: no such term file")
    mod_name = f"_imu_bench_terms_{abs(hash(str(p.resolve())))}"
    spec = importlib.util.spec_from_file_location(mod_name, p)
    if spec is None or spec.loader is None:
        raise UserError(f"{p}: cannot load it as Python")
    module = importlib.util.module_from_spec(spec)
    sys.modules[mod_name] = module
    try:
        spec.loader.exec_module(module)
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
