"""The commands of ``python3 -m host``, one module each (thin: parse, call the library, print).

- ``archive`` — ``archive``: every calibration kept by serial, the lot's statistics;
  ``archive_text`` — its answers as text within the terminal's width.
- ``calibrate`` — ``calibrate``: live (the dialogue) or ``--from-dir``.
- ``capture`` — ``capture``: record a port's bytes with host read times.
- ``decode`` — ``decode``: a capture or raw bytes as samples, CSV/JSON lines, statistics.
- ``flash`` — ``flash``: build, flash and check the firmware.
- ``importing`` — ``import``: foreign data into records.
- ``exporting`` — ``export``: the result in another tool's format.
- ``model`` — ``model``: the workbench; ``demo`` — ``demo``: an effect hidden in a simulated
  session, found by it.
- ``noise`` — ``noise``: Allan deviation and noise figures of a recording; ``noise_source`` —
  the capture it streams, in bounded memory at any length.
- ``plan`` — ``plan``: which record to measure next.
- ``thermal`` — ``thermal``: bias against temperature.

Shared by the commands: ``options`` (``options.py``): each command's typed options, read once
from its arguments (a frozen dataclass per command, built at this edge: nothing else reads the
argparse namespace), and the argument groups commands share — the model and its term files, the
noise floor, the site, the workbench's records, the archive; :func:`pyplot` (the one place that
says how to get matplotlib), :func:`out_directory` (an ``--out`` directory made if missing), and
``screen`` (``screen.py``): the width rule — text wrapped at words within the terminal, tables
narrowed, long commands broken so they still run, the progress line of a long wait; and
``figures`` (``figures.py``): the plots of ``model``, ``noise`` and ``thermal``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from host.errors import UserError

#: what --plot says when matplotlib is missing (every command says the same)
NO_MATPLOTLIB = (
    "--plot needs matplotlib: pip install matplotlib (in a checkout of this project: "
    "pip install -e '.[plot]')"
)


def pyplot() -> Any:
    """matplotlib.pyplot on the file-only Agg backend, or a UserError saying how to install it."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:
        raise UserError(NO_MATPLOTLIB) from exc
    return plt


def out_directory(path: str | Path) -> Path:
    """The ``--out`` directory, made (with its parents) when it does not exist yet; a file in
    the way is a UserError naming it."""
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        blocker = next((p for p in (out, *out.parents) if p.exists() and not p.is_dir()), out)
        raise UserError(f"--out {out}: {blocker} is a file; give --out a directory") from None
    return out
