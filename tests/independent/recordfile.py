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

from collections.abc import Mapping
from pathlib import Path

import numpy as np

#: decimals of time, Ax, Ay, Az, Gx, Gy, Gz, temp
COLUMN_DECIMALS = (1, 4, 4, 4, 3, 3, 3, 1)


def _num(v: float, dec: int) -> str:
    s = f"{v:.{dec}f}"
    return s[1:] if s.startswith("-") and float(s) == 0.0 else s


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
    data = np.column_stack([t_ms, accel, gyro, temp_c])
    printed = np.empty_like(data)
    for row_i, row in enumerate(data):
        cells = [_num(float(v), d) for v, d in zip(row, COLUMN_DECIMALS, strict=True)]
        lines.append("\t".join(cells))
        printed[row_i] = [float(c) for c in cells]
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
