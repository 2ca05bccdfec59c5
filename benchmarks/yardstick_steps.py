"""The yardstick's bias steps (issue 24): where a step was placed against the truth.

Used by :mod:`benchmarks.yardstick` for its step cases (``step_*``, ``two_steps_*``): each
session's true step times on the records' clock, whether the records tell two steps from one,
and the table of placements (named, two named, the 95 % ± holding the truth, its width and
error inside a record, the sizes' pulls).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np


def records_clock(s: Any, at: float) -> list[Any]:
    """[time, inside a record?] of a true time ``at`` (s since power-on) on the records'
    clock, which starts each record at its first sample (its ``power_on_s``): the simulator
    starts a record up to one sample period before its first sample, so a time inside it is
    moved back by that much. ``s``: the simulated session."""
    for r in s.records:
        start = float(r.meta["power_on_s"])
        if start + float(r.t_ms[0]) / 1e3 < at < start + float(r.t_ms[-1]) / 1e3:
            return [at - float(r.t_ms[0]) / 1e3, True]
    return [at, False]


def two_tell(d: Path, effect: dict[str, Any], at: Sequence[float]) -> bool:
    """Do the records in ``d`` tell the two true steps (at their true times ``at``, s on the
    records' clock) from the best one step anywhere on the channel, alone or with a drift
    (Bonferroni over the scan's cuts at 5 %)? Where they do not, one step elsewhere (or with a
    drift) does as well: the check that two are named counts only where they do."""
    from host.model.components import fit_with_components
    from host.model.dataset import load_dataset
    from host.model.signals import AXES
    from host.model.spec import parse_model
    from host.model.stats import chi2_sf
    from host.workbench.scan import step_cuts, time_column
    from host.workbench.steps import channel_cuts, two_against_one

    joint = fit_with_components(load_dataset(d), parse_model("base"))
    ds, fit = joint.dataset, joint.fit
    cuts = channel_cuts(ds, fit.basis, effect["sensor"], AXES.index(effect["axis"]))
    if cuts is None:
        return False
    drift = time_column(ds, fit, effect["sensor"], effect["axis"])
    gain = two_against_one(cuts, fit.white_residual, at[0], at[1], drift)
    return bool(chi2_sf(gain, 1) * len(step_cuts(ds)) < 0.05)


def _median(x: Sequence[float]) -> float:
    return float(np.median(np.asarray(x, dtype=float))) if len(x) else math.nan


def step_stats(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Where the steps were placed against the truth: sessions whose top signal names as many
    steps as there were on the right channel (``named``) and with two named (``two``); true
    steps whose ± holds them (``cover``; ``cover_in`` of ``n_in`` inside a record, where the ±
    is a time read from a row, not a gap); the median ± and |error| inside a record, s; the
    sd of the sizes' pulls (fitted − truth)/σ. Sessions with two steps count only where the
    records tell them from one step (``tell``)."""
    named = two = cover = n_true = cover_in = n_in = tell = 0
    width: list[float] = []
    err: list[float] = []
    pulls: list[float] = []
    for r in rows:
        truth = r["step_truth"]
        e = r["effect"]
        if not r.get("two_tell", True):
            continue  # two steps the records cannot tell from one: counted apart
        tell += len(truth) == 2
        n_true += len(truth)
        n_in += sum(bool(t[1]) for t in truth)
        top = r["signals"][0] if r["signals"] else {}
        placed = top.get("steps") or []
        if (top.get("sensor"), top.get("axis")) != (e["sensor"], e["axis"]) or not placed:
            continue
        named += len(placed) == len(truth)
        two += len(placed) == 2
        for k, (at, inside, size) in enumerate(truth):
            # the named step that stands for this one: the same rank in time when as many
            # were named, else the nearest
            if len(placed) == len(truth):
                p = placed[k]
            else:
                p = min(placed, key=lambda q: abs(float(q["at_s"]) - at))
            held = float(p["lo_s"]) <= at <= float(p["hi_s"])
            cover += held
            pulls.append((float(p["size"]) - size) / float(p["size_sd"]))
            if inside:
                cover_in += held
                width.append(max(float(p["at_s"]) - float(p["lo_s"]),
                                 float(p["hi_s"]) - float(p["at_s"])))  # fmt: skip
                err.append(abs(float(p["at_s"]) - at))
    return {
        "named": named, "two": two, "tell": tell, "cover": cover, "n_true": n_true,
        "cover_in": cover_in, "n_in": n_in, "pm_in_med": _median(width),
        "err_in_med": _median(err),
        "size_pull_sd": float(np.std(pulls, ddof=1)) if len(pulls) > 1 else math.nan,
    }  # fmt: skip


def steps_table(summary: dict[str, Any]) -> list[str]:
    """The placements of every case with steps, as text lines (none when no case has)."""
    stepped = [k for k in summary if "steps" in summary[k]]
    if not stepped:
        return []
    lines = [
        "",
        "== steps placed: tell = sessions whose two steps the records tell from one",
        "   (two-step cases; the others are left out of the rest); named = the top",
        "   signal names as many steps as there were, on the right channel; two =",
        "   sessions with two named; cover = true steps inside the stated ± (95 %),",
        "   all / inside a record; ± and |err| = medians inside a record, s;",
        "   size sd = sd of the sizes' (fitted − truth)/σ",
        f"{'case':<17}{'n':>4}{'tell':>5}{'named':>7}{'two':>5}{'cover':>9}"
        f"{'in record':>11}{'±':>7}{'|err|':>7}{'size sd':>9}",
    ]
    for k in stepped:
        st = summary[k]["steps"]
        nums = [f"{x:.2f}" if math.isfinite(x) else "—"
                for x in (st["pm_in_med"], st["err_in_med"], st["size_pull_sd"])]  # fmt: skip
        lines.append(
            f"{k:<17}{summary[k]['n']:>4}{st['tell'] or '—':>5}{st['named']:>7}{st['two']:>5}"
            f"{str(st['cover']) + '/' + str(st['n_true']):>9}"
            f"{str(st['cover_in']) + '/' + str(st['n_in']):>11}"
            f"{nums[0]:>7}{nums[1]:>7}{nums[2]:>9}"
        )
    return lines
