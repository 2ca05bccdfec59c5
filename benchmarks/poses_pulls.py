"""Poses without a cube on data the bench did not write (issue 41's Done-when): sessions of the
independent simulator (``tests/independent/poses.py``: random attitudes, moves about random
axes, the unit's scale, misalignment, bias, g-sensitivity, noise, quantisation) calibrated with
``calibrate_from_records``; prints per session the largest |fitted − truth|/σ, the largest
scale error, and over all sessions the pulls' mean and SD per parameter family, and the
hand-held pose's variance components (``--creep``: the hand turns the unit at that rate, °/s
per axis, during each rest).

    OPENBLAS_NUM_THREADS=1 python3 benchmarks/poses_pulls.py --sessions 50 --poses 30
    OPENBLAS_NUM_THREADS=1 python3 benchmarks/poses_pulls.py --sessions 50 --poses 30 --creep 0.02
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from host.calib.calibration import CalibrationOptions, calibrate_from_records  # noqa: E402
from host.session.directory import read_session  # noqa: E402
from tests.independent.poses import PoseSpec, simulate_poses, truth_in_frame, write_poses  # noqa: E402


def session_pulls(
    seed: int, poses: int, creep: float = 0.0, components: dict[str, list[float]] | None = None
) -> dict[str, tuple[float, float, float]]:
    """name -> (fitted, σ, truth in the accelerometer's frame) of every determined value; the
    pose components' values appended to ``components`` (name -> values)."""
    spec = PoseSpec(seed=seed, poses=poses, creep_dps=creep)
    sess = simulate_poses(spec)
    with tempfile.TemporaryDirectory() as d:
        write_poses(d, sess)
        res = calibrate_from_records(
            read_session(d),
            CalibrationOptions(latitude_deg=spec.latitude_deg, height_m=spec.height_m),
        )
    assert sess.truth is not None
    truth = truth_in_frame(sess.truth)
    for line in res.notes:
        for name in ("pose rate", "pose hold"):
            if components is not None and line.startswith(f"a named variance component: {name}: "):
                value = line.split(": ")[2].split(" ")[0]
                components.setdefault(name, []).append(float(value))
    return {
        p.name: (p.value, p.stderr, truth[p.name])
        for p in res.parameters
        if p.name in truth and math.isfinite(p.value) and p.stderr > 0
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sessions", type=int, default=50)
    ap.add_argument("--poses", type=int, default=30)
    ap.add_argument("--seed0", type=int, default=1000)
    ap.add_argument("--creep", type=float, default=0.0, help="the hand's rate in a pose, °/s")
    args = ap.parse_args()
    comps: dict[str, list[float]] = {}
    families: dict[str, list[float]] = {}
    worst_scale = 0.0
    for k in range(args.sessions):
        got = session_pulls(args.seed0 + k, args.poses, args.creep, comps)
        z = {n: (v - t) / s for n, (v, s, t) in got.items()}
        for n, zz in z.items():
            own = n[0] + ("s" if n[1] == n[2] else "m")
            fam = n[:2] if n.startswith(("A0", "G0", "GA")) else own
            families.setdefault(fam, []).append(zz)
        scales = [abs(v - t) for n, (v, s, t) in got.items() if len(n) == 3 and n[1] == n[2]]
        worst_scale = max(worst_scale, max(scales, default=0.0))
        print(
            f"session {k}: {len(z)} values, max |z| {max(abs(v) for v in z.values()):.2f}, "
            f"scale error max {max(scales, default=math.nan):.2g}",
            flush=True,
        )
    everything = np.concatenate([np.array(v) for v in families.values()])
    for fam, vals in sorted(families.items()):
        a = np.array(vals)
        print(
            f"{fam:3s} n={len(a):4d} mean {a.mean():+.2f} SD {a.std(ddof=1):.2f} "
            f"beyond 3: {np.mean(np.abs(a) > 3):.3f}"
        )
    print(
        f"all n={len(everything)} SD {everything.std(ddof=1):.2f}; "
        f"largest scale error {worst_scale:.2g}"
    )
    for name, values in sorted(comps.items()):
        v = np.array(values)
        print(
            f"{name}: resolved in {np.count_nonzero(v)} of {len(v)} sessions, median "
            f"{np.median(v):.3g}, mean {v.mean():.3g}, max {v.max():.3g}"
        )


if __name__ == "__main__":
    main()
