"""Our own writer of the project's record file format (method.md §6; the format as the README
states it), so that the independent simulator depends on the format, not on the host's code.

A file ``SERIAL_name.txt``::

    # imu-bench record v1
    # key: value            (header lines)
    t_ms<TAB>Ax<TAB>Ay<TAB>Az<TAB>Gx<TAB>Gy<TAB>Gz<TAB>temp     (ms 1 dec; m/s² 4; °/s 3; °C 1)
    ________________________________________
    mean<TAB>… 7 means of the printed rows (4 decimals)
    std<TAB>…  7 sample standard deviations (ddof 1, 4 decimals)
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

#: decimals of time, Ax, Ay, Az, Gx, Gy, Gz, temp
COLUMN_DECIMALS = (1, 4, 4, 4, 3, 3, 3, 1)


def _num(v: float, dec: int) -> str:
    s = f"{v:.{dec}f}"
    return s[1:] if s.startswith("-") and float(s) == 0.0 else s


#: one data row as printed (``str.format`` of the floats, the columns' decimals)
_ROW = "\t".join(f"{{:.{d}f}}" for d in COLUMN_DECIMALS)
#: a cell printed as minus zero ("-0.000"): printed without its sign, as :func:`_num` does
_MINUS_ZERO = re.compile(r"(?<![^\t\n])-(0\.0+)(?![^\t\n])")


def _rows(data: np.ndarray) -> tuple[str, np.ndarray]:
    """The data rows' text (one line each, no final newline) and the values printed in them:
    each cell as :func:`_num` prints it, the whole table formatted at once (most of a
    simulated session's time went into formatting cell by cell)."""
    text = _MINUS_ZERO.sub(r"\1", "\n".join(_ROW.format(*row) for row in data.tolist()))
    printed = np.array(text.split(), dtype=float).reshape(data.shape)
    return text, printed


def record_text(
    name: str,
    meta: Mapping[str, str],
    t_ms: np.ndarray,
    accel: np.ndarray,
    gyro: np.ndarray,
    temp_c: np.ndarray,
) -> str:
    """The file text of one record: ``t_ms`` (N,) ms, ``accel`` (N, 3) m/s², ``gyro`` (N, 3)
    °/s, ``temp_c`` (N,) °C; ``meta`` header lines (``record`` is added)."""
    lines = ["# imu-bench record v1"]
    lines += [f"# {k}: {v}" for k, v in meta.items()]
    lines.append(f"# record: {name}")
    data = np.column_stack([t_ms, accel, gyro, temp_c]).astype(float)
    rows, printed = _rows(data)
    if len(data):
        lines.append(rows)
    lines.append("_" * 72)
    mean = printed[:, 1:].mean(axis=0)
    std = printed[:, 1:].std(axis=0, ddof=1)
    lines.append("mean\t" + "\t".join(_num(float(v), 4) for v in mean))
    lines.append("std\t" + "\t".join(_num(float(v), 4) for v in std))
    return "\n".join(lines) + "\n"


def write_record_file(directory: Path, serial: str, name: str, text: str) -> Path:
    """Write ``directory/SERIAL_name.txt`` (UTF-8, LF) and return its path."""
    p = Path(directory) / f"{serial}_{name}.txt"
    p.write_text(text, encoding="utf-8", newline="\n")
    return p
