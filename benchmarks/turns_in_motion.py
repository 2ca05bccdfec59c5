"""Turn records that start or end in motion (issue 39 item 6), on the independent simulator.

Sessions of ``tests/independent`` (the six faces, two turns each way about each axis, the
closing x_up) in which one to three turn records, drawn at random, are cut in motion: the
record starts after the hand has turned 0.3–15° or ends that many degrees before it stops
(``SessionSpec.turn_cut``), so its integral is not 720° and its first or last samples turn at
tens of °/s. Each session is calibrated as a user would (``calibrate_from_records``, the base
model, the floor from the session); per gyro scale and cross-axis value the pull
(fitted − truth)/σ where it is determined, and whether the values left undetermined are
exactly those of an axis whose turns are all in motion (its scale, and the two cross-axis
values read in its turns: the angle trades with them).

    OPENBLAS_NUM_THREADS=1 python3 benchmarks/turns_in_motion.py --sessions 50
    OPENBLAS_NUM_THREADS=1 python3 benchmarks/turns_in_motion.py --sessions 50 --first 9200 \
        --motion continuous
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")  # before numpy loads: one BLAS thread

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from host.calib.calibration import calibrate_from_records  # noqa: E402
from host.session.directory import read_session  # noqa: E402
from tests.independent.simulate import TURNS, SessionSpec, write_session  # noqa: E402

#: the gyro's scales, then its cross-axis values (method.md §2)
SCALES = ("Gxx", "Gyy", "Gzz")
CROSS = ("Gxz", "Gxy", "Gyz", "Gyx", "Gzy", "Gzx")
#: the values a turn about each axis reads: its scale and the two cross-axis values of the
#: other channels (method.md §4: I^y_{X±} gives Gyz, I^z_{X±} gives Gzy)
READ_IN = {"x": ("Gxx", "Gyz", "Gzy"), "y": ("Gyy", "Gxz", "Gzx"), "z": ("Gzz", "Gxy", "Gyx")}


def cuts_of(
    seed: int, lo_deg: float = 0.3, hi_deg: float = 15.0
) -> tuple[tuple[str, str, float], ...]:
    """One to three turn records of session ``seed``, each cut at a random end by a random
    angle in [``lo_deg``, ``hi_deg``]° (:attr:`SessionSpec.turn_cut`)."""
    rng = np.random.default_rng([seed, 77])
    names = rng.choice(TURNS, size=int(rng.integers(1, 4)), replace=False)
    return tuple(
        (str(n), str(rng.choice(["starts", "ends"])), float(rng.uniform(lo_deg, hi_deg)))
        for n in names
    )


def expected_undetermined(cuts: Sequence[tuple[str, str, float]]) -> set[str]:
    """The values no record fixes: those read in the turns about an axis whose two turns are
    both in motion."""
    cut = {c[0] for c in cuts}
    return {v for ax, vals in READ_IN.items() if {f"{ax}_ccw", f"{ax}_cw"} <= cut for v in vals}


def session_pulls(directory: Path, spec: SessionSpec) -> tuple[dict[str, float], set[str]]:
    """(value -> pull (fitted − truth)/σ where determined, the values not determined) of the
    calibration of the session ``spec`` written into ``directory``."""
    truth = write_session(directory, spec).truth()["constants"]
    res = calibrate_from_records(read_session(directory))
    values, sigmas = res.constants(), res.std_errors
    pulls: dict[str, float] = {}
    undetermined: set[str] = set()
    for name in SCALES + CROSS:
        v, sd = values[name], sigmas.get(name, math.nan)
        if math.isfinite(v) and math.isfinite(sd) and sd > 0:
            pulls[name] = (v - float(truth[name])) / sd
        else:
            undetermined.add(name)
    return pulls, undetermined


def run(seeds: Sequence[int], motion: str) -> dict[str, object]:
    """Every session's pulls, and the sessions whose undetermined values are not those
    :func:`expected_undetermined` names."""
    pulls: dict[str, list[float]] = {n: [] for n in SCALES + CROSS}
    wrong: list[int] = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in seeds:
            spec = SessionSpec(seed=seed, turn_cut=cuts_of(seed), turn_motion=motion)
            got, undetermined = session_pulls(Path(tmp) / str(seed), spec)
            for name, z in got.items():
                pulls[name].append(z)
            if undetermined != expected_undetermined(spec.turn_cut):
                wrong.append(seed)
    return {"pulls": pulls, "wrong_undetermined": wrong}


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sessions", type=int, default=50)
    ap.add_argument("--first", type=int, default=9100, help="the first session's seed")
    ap.add_argument("--motion", choices=("quarters", "continuous"), default="quarters")
    args = ap.parse_args(argv)
    out = run(range(args.first, args.first + args.sessions), args.motion)
    pulls = out["pulls"]
    assert isinstance(pulls, dict)
    print(f"{args.sessions} sessions, turns as {args.motion}, 1–3 turn records cut in motion")
    print(f"{'value':<8}{'n':>4}{'pull SD':>9}{'mean':>8}")
    for name in SCALES + CROSS:
        z = np.array(pulls[name])
        print(f"{name:<8}{len(z):>4}{z.std():>9.2f}{z.mean():>+8.2f}")
    for label, names in (("scales", SCALES), ("cross-axis", CROSS)):
        z = np.concatenate([pulls[n] for n in names])
        print(f"{label}: {len(z)} pulls, SD {z.std():.2f}, mean {z.mean():+.2f}")
    wrong = out["wrong_undetermined"]
    print(f"sessions whose undetermined values are not the all-in-motion axes': {wrong or 'none'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
