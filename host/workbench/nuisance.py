"""Per-record unknowns tested against the shared parameter they stand for.

A static record whose heading on a tilted plate is not recorded carries the plate's tilt as it
sees it, two angles of its own (``plate_tilt.REC.seen_ref``, ``.seen_side``,
:mod:`host.model.plate`): their direction against the plate's is the record's heading, which
nothing fixes, but their size is the plate's tilt when the record sat on the plate as the turns
did. :func:`seen_tilt_test` compares each record's size with the one plate tilt (the fit's
``plate_tilt.east``, ``.north``), through the fit's covariance of all of them: a record off it
by many σ sat otherwise (a fixture face's error, a re-seating), which the per-record unknowns
absorb without a word. The sizes are compared only where the plate's tilt is well above its
σ (a size near zero is biased upward).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from host.model.fit import Fit
from host.model.stats import chi2_sf

#: the parameters of one record's own view of the tilt, and the plate's own two
VIEW = ("seen_ref", "seen_side")
PLATE = ("plate_tilt.east", "plate_tilt.north")
#: the plate's tilt must be this many σ above zero for sizes to be compared
MIN_SIZE_SIGMAS = 3.0


@dataclass(frozen=True)
class SeenTilt:
    """One record's view of the tilt: its size and σ, and its departure from the plate's
    tilt in σ of the difference (rad)."""

    record: str
    size: float
    size_sd: float
    z: float


@dataclass(frozen=True)
class SeenTiltTest:
    """The records' views against the plate's tilt ``plate`` ± ``plate_sd`` (rad): χ² of the
    size differences on ``dof`` (one per record), with their correlation through the plate."""

    plate: float
    plate_sd: float
    views: tuple[SeenTilt, ...]
    chi2: float
    dof: int
    p_value: float

    def describe(self) -> str:
        """One sentence for people (mrad)."""
        worst = max(self.views, key=lambda v: abs(v.z))
        sizes = [1000 * v.size for v in self.views]
        verdict = (
            "they do not all sit on the plate as the turns do (a fixture face's error or a "
            "re-seating: each record's own unknowns take it without a word)"
            if self.p_value < 0.01
            else "consistent with one plate tilt"
        )
        return (
            f"the static records' own views of the tilt ({len(self.views)} records, "
            f"{min(sizes):.1f}–{max(sizes):.1f} mrad) against the plate's one tilt "
            f"{1000 * self.plate:.2f} ± {1000 * self.plate_sd:.2f} mrad: χ² = {self.chi2:.1f} "
            f"on {self.dof} dof (p = {self.p_value:.2g}); worst {worst.record} "
            f"{1000 * worst.size:.2f} ± {1000 * worst.size_sd:.2f} mrad ({worst.z:+.1f} σ): "
            + verdict
        )


def seen_tilt_test(fit: Fit) -> SeenTiltTest | None:
    """Each record's own view of the plate's tilt against the plate's (module docstring);
    None when the fit has no such views, no covariance, or a tilt too small to compare."""
    index = {p.name: i for i, p in enumerate(fit.parameters)}
    records = sorted({n.split(".")[1] for n in index
                      if n.startswith("plate_tilt.") and n.endswith("." + VIEW[0])})  # fmt: skip
    cov = fit.covariance
    if not records or cov is None or not all(n in index for n in PLATE):
        return None
    value = np.array([p.value for p in fit.parameters])
    plate_i = [index[n] for n in PLATE]
    plate, g_plate = _size(value, plate_i)
    plate_sd = math.sqrt(max(float(g_plate @ cov[np.ix_(plate_i, plate_i)] @ g_plate), 0.0))
    if not math.isfinite(plate_sd) or plate <= MIN_SIZE_SIGMAS * plate_sd:
        return None
    diffs, jac, sizes, sds = [], [], [], []
    for rec in records:
        own = [index.get(f"plate_tilt.{rec}.{v}", -1) for v in VIEW]
        if min(own) < 0:
            continue
        size, g = _size(value, own)
        row = np.zeros(len(value))
        row[own] = g
        sds.append(math.sqrt(max(float(row @ cov @ row), 0.0)))
        row[plate_i] -= g_plate
        diffs.append(size - plate)
        jac.append(row)
        sizes.append((rec, size))
    if not diffs:
        return None
    j = np.array(jac)
    d = np.array(diffs)
    cd = j @ cov @ j.T
    if not np.all(np.isfinite(cd)):
        return None
    chi2 = float(d @ np.linalg.lstsq(cd, d, rcond=None)[0])
    zs = d / np.sqrt(np.maximum(np.diag(cd), 1e-30))
    views = tuple(SeenTilt(r, s, sd, float(z))
                  for (r, s), sd, z in zip(sizes, sds, zs, strict=True))  # fmt: skip
    return SeenTiltTest(plate, plate_sd, views, chi2, len(d), chi2_sf(chi2, len(d)))


def _size(value: np.ndarray, idx: list[int]) -> tuple[float, np.ndarray]:
    """The size of the two angles at ``idx`` and its gradient with respect to them."""
    a, b = float(value[idx[0]]), float(value[idx[1]])
    size = math.hypot(a, b)
    g = np.array([a, b]) / size if size > 0 else np.zeros(2)
    return size, g
