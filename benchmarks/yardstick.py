"""An honest yardstick for the model workbench (issues 24 and 25), on data it did not write.

Generates sessions with the independent simulator (``tests/independent``: white noise,
quantisation, one effect each), runs the project's workbench on them through its command line
with the floor taken from the session (no ``--floor``, no ``--noise``), and prints, per case,
the Done-when quantities of issues 24 and 25:

* controls: median RMS z (10th–90th percentile), χ²/dof, the fraction flagged at the 5 % level
  and the Kolmogorov–Smirnov p of the p-values against uniform;
* per effect: the verdicts, whether the expected catalogue term is recommended (catalogue
  effects) or a single catalogue term is recommended anyway (off-catalogue effects), whether
  the top unexplained signal is the right one, RMS z before → after adding what was
  recommended, and the share that falls ≥ 3× to ≤ 1.5;
* pulls (fitted − truth)/σ of every recovered coefficient (the expected term added to the
  base model) and of the calibration constants (``calibrate --from-dir`` on the controls):
  mean, standard deviation, share beyond 3;
* plate tilt recovered vs truth (magnitude ratio, within 10 %, within 2σ).

Run in chunks and merge: every session is one JSON line in ``--out`` (appended), and
``--report FILE…`` prints the tables from saved lines without running anything::

    OPENBLAS_NUM_THREADS=1 python3 benchmarks/yardstick.py --cases control --sessions 50 \\
        --out /tmp/yard.jsonl
    python3 benchmarks/yardstick.py --report /tmp/yard.jsonl

The functions :func:`run_session` and :func:`summarise` are reusable from tests.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")  # before numpy loads: one BLAS thread

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.yardstick_pulls import (  # noqa: E402
    Truth,
    effect_of,
    pull_group,
    pull_stats,
    pulls_of,
)
from benchmarks.yardstick_steps import records_clock, step_stats, steps_table, two_tell  # noqa: E402
from tests.independent.effects import STEP_PLACES  # noqa: E402
from tests.independent.physics import ACCEL_LSB, FS_HZ, GYRO_LSB  # noqa: E402
from tests.independent.simulate import SessionSpec, write_session  # noqa: E402

#: the workbench states its floor only in words: "noise floor of a record mean: accel 0.00075
#: m/s² from …; gyro 0.0017 °/s from …"
_FLOOR_RE = re.compile(r"\b(accel|gyro) ([0-9.]+(?:e-?[0-9]+)?) (?:m/s²|°/s)")


@dataclass(frozen=True)
class Case:
    """One kind of session: the simulator's ``spec`` fields, what kind of effect it hides,
    the catalogue term that models it (from the truth) and the signal a scan should name."""

    name: str
    spec: dict[str, Any]
    kind: str  # "control" | "catalogue" | "off"
    term: Callable[[Truth], str] | None = None
    signal: Callable[[dict[str, Any], Truth], bool] | None = None
    calibrate: bool = False
    plate: bool = False
    #: catalogue terms that, significant on the effect's channel, count as naming it (a step
    #: or a drift "named as a step or drift": time_drift)
    names: tuple[str, ...] = ()
    #: catalogue terms that must never be recommended on this case (a wrong geometry)
    wrong: tuple[str, ...] = ()


def _on_axis(term: str) -> Callable[[Truth], str]:
    return lambda t: f"{term}:{effect_of(t)['sensor']}:{effect_of(t)['axis']}"


def _signal(*words: str, source: bool = False) -> Callable[[dict[str, Any], Truth], bool]:
    """The scan's signal is on the effect's channel and its name holds one of ``words``
    (and the effect's source axis, for cross-axis effects)."""

    def match(sig: dict[str, Any], t: Truth) -> bool:
        e = effect_of(t)
        if sig.get("sensor") != e["sensor"] or sig.get("axis") != e["axis"]:
            return False
        name = str(sig.get("signal", "")).lower()
        if source and f"force {e['source']}" not in name:
            return False
        return any(w.lower() in name for w in words)

    return match


_STEP = _signal("step", "jump")
_DRIFT = _signal("time", "drift")
_DTDT = _signal("dt/dt", "temperature rate", "rate of change of temperature", "warming rate")
_SQUARE = _signal(")²", source=True)
_ABS = _signal("|specific force", source=True)

CASES: dict[str, Case] = {
    c.name: c
    for c in [
        Case("control", {"effect": "none"}, "control", calibrate=True),
        Case("plate_tilt_h0", {"effect": "plate_tilt"}, "catalogue",
             term=lambda t: "plate_tilt:accel", plate=True),
        Case("plate_tilt_rec", {"effect": "plate_tilt", "headings": "random",
                                "record_heading": True}, "catalogue",
             term=lambda t: "plate_tilt:accel", plate=True),
        Case("plate_tilt_unrec", {"effect": "plate_tilt", "headings": "random"}, "catalogue",
             term=lambda t: "plate_tilt:accel", plate=True),
        # the method's bench (issue 40): each turn in one motion, resting only at its ends
        Case("plate_tilt_motion", {"effect": "plate_tilt", "headings": "random",
                                   "turn_motion": "continuous"}, "catalogue",
             term=lambda t: "plate_tilt:accel", plate=True, wrong=("lever_arm", "face_error")),
        Case("lever_arm_motion", {"effect": "lever_arm_mm", "headings": "random",
                                  "turn_motion": "continuous"}, "catalogue",
             term=lambda t: "lever_arm:accel", wrong=("plate_tilt", "face_error")),
        Case("tilt_lever_motion", {"effect": "plate_tilt_lever_arm", "headings": "random",
                                   "turn_motion": "continuous"}, "catalogue",
             term=lambda t: "plate_tilt:accel,lever_arm:accel", plate=True,
             wrong=("face_error",)),
        Case("turn_axis_tilt", {"effect": "turn_axis_tilt"}, "catalogue", calibrate=True,
             signal=lambda s, t: False),
        Case("face_lean", {"effect": "face_lean"}, "catalogue", term=lambda t: "face_error:accel"),
        Case("lever_arm", {"effect": "lever_arm"}, "catalogue", term=lambda t: "lever_arm:accel"),
        Case("drift_accel", {"effect": "bias_drift_accel"}, "catalogue",
             term=_on_axis("time_drift"), signal=_DRIFT, names=("time_drift",)),
        Case("drift_gyro", {"effect": "bias_drift_gyro"}, "catalogue",
             term=_on_axis("time_drift"), signal=_DRIFT, names=("time_drift",)),
        Case("temp_bias", {"effect": "temperature_bias", "warmup_s": 120.0}, "catalogue",
             term=_on_axis("temperature_bias")),
        Case("asym_gyro", {"effect": "scale_asymmetry"}, "catalogue",
             term=_on_axis("scale_asymmetry")),
        Case("nonlin_gyro", {"effect": "scale_nonlinearity"}, "catalogue",
             term=_on_axis("scale_nonlinearity")),
        Case("step_accel", {"effect": "bias_step_accel"}, "off", signal=_STEP,
             names=("time_drift",)),
        Case("step_gyro", {"effect": "bias_step_gyro"}, "off", signal=_STEP,
             names=("time_drift",)),
        *(Case(f"step_{s}_{w}", {"effect": f"bias_step_{s}_{w}"}, "off", signal=_STEP,
               names=("time_drift",)) for w in ("early", "late") for s in ("accel", "gyro")),
        *(Case(f"step_{s}_at_{w}", {"effect": f"bias_step_{s}_at_{w}"}, "off", signal=_STEP,
               names=("time_drift",)) for w in STEP_PLACES for s in ("accel", "gyro")),
        # the same without the closing x_up_2 (a plan that ends on its turns)
        *(Case(f"step_{s}_at_{w}_open", {"effect": f"bias_step_{s}_at_{w}", "closing": False},
               "off", signal=_STEP, names=("time_drift",))
          for w in STEP_PLACES if w not in ("closing", "in_last") for s in ("accel", "gyro")),
        *(Case(f"two_steps_{s}", {"effect": f"bias_two_steps_{s}"}, "off", signal=_STEP,
               names=("time_drift",)) for s in ("accel", "gyro")),
        Case("dtdt_gyro", {"effect": "dtdt_bias", "warmup_s": 120.0}, "off", signal=_DTDT),
        Case("cross_g2", {"effect": "cross_g2"}, "off", signal=_SQUARE),
        Case("abs_leak", {"effect": "abs_leak"}, "off", signal=_ABS),
        Case("gyro_g2", {"effect": "gyro_g2"}, "off", signal=_SQUARE),
    ]
}  # fmt: skip


# ---- running the workbench ----------------------------------------------------------------
def host_json(args: Sequence[str]) -> dict[str, Any]:
    """Run ``python3 -m host ARGS --json`` (BLAS on one thread) and return its JSON; a failure
    returns ``{"error": <the last line of stderr>, "exit": code}``."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    p = subprocess.run(
        [sys.executable, "-m", "host", *args, "--json"],
        capture_output=True, text=True, cwd=ROOT, env=env, timeout=600,
    )  # fmt: skip
    try:
        return dict(json.loads(p.stdout))
    except json.JSONDecodeError:
        lines = (p.stderr or p.stdout).strip().splitlines()
        return {"error": lines[-1] if lines else "no output", "exit": p.returncode}


def white_of_mean(spec: SessionSpec) -> dict[str, float]:
    """Standard deviation of a static record's mean from its white noise and quantisation
    alone (the truth the floor should not exceed by much), per sensor."""
    n = spec.static_s * FS_HZ
    return {
        "accel": math.hypot(spec.accel_density * math.sqrt(FS_HZ / 2), ACCEL_LSB / 12**0.5)
        / math.sqrt(n),
        "gyro": math.hypot(spec.gyro_density * math.sqrt(FS_HZ / 2), GYRO_LSB / 12**0.5)
        / math.sqrt(n),
    }


def run_session(case: Case, seed: int, workdir: Path) -> dict[str, Any]:
    """Simulate one session of ``case`` and measure the workbench on it: one JSON-able row."""
    d = workdir / f"{case.name}_{seed}"
    spec = SessionSpec(seed=seed, **case.spec)
    s = write_session(d, spec)
    truth = s.truth()
    row: dict[str, Any] = {"case": case.name, "seed": seed, "effect": truth["effect"]}
    diag = host_json(["model", "diagnose", str(d)])
    if "error" in diag:
        row["error"] = diag["error"]
        return row
    fit = diag["fit"]
    row.update(
        rms_z=fit["rms_z"], p=fit["chi2_p"], chi2_dof=fit["chi2"] / max(fit["dof"], 1),
        verdict=diag["verdict"], recommended=diag["recommended"],
        signals=[{k: s.get(k) for k in ("sensor", "axis", "signal", "text", "steps")}
                 for s in diag.get("unexplained_signals", [])[:3]],
        significant=[c["label"] for c in diag.get("candidates", []) if c.get("significant")][:5],
        equals=[{"terms": e["terms"], "signals": e["signals"]} for e in diag.get("equals", [])],
    )  # fmt: skip
    for note in diag.get("notes", []):
        if str(note).startswith("noise floor of a record mean:"):
            row["floor"] = {m[0]: float(m[1]) for m in _FLOOR_RE.findall(str(note))}
    row["white_mean"] = white_of_mean(spec)
    e = truth["effect"]
    if "at_session_s" in e:  # bias steps: their times since power-on, sizes, in a record?
        at = [(e["at_session_s"], e["step"])]
        if "at_session_s_2" in e:
            at.append((e["at_session_s_2"], e["step_2"]))
        row["step_truth"] = [records_clock(s, a + spec.warmup_s) + [size] for a, size in at]
        if len(at) == 2:
            row["two_tell"] = two_tell(d, e, [t[0] for t in row["step_truth"]])
    if diag["recommended"]:
        add = host_json(["model", "add", str(d), diag["recommended"], "--model", "base"])
        row["rms_z_after_rec"] = add.get("after", {}).get("rms_z")
        # before on the yardstick the term was tested on (a term that moves the turn closures:
        # without the turn angle of its axes), as `model add` prints it
        row["rms_z_before_rec"] = add.get("before", {}).get("rms_z")
    if case.term is not None:
        term = case.term(truth)
        row["term"] = term
        add = host_json(["model", "add", str(d), term, "--model", "base"])
        if "error" in add:
            row["term_error"] = add["error"]
        else:
            row["rms_z_after_term"] = add["after"]["rms_z"]
            row["rms_z_before_term"] = add["before"]["rms_z"]
            row["coef"] = pulls_of(add["new_parameters"], truth)
    if case.calibrate:
        cal = host_json(["calibrate", "--from-dir", str(d)])
        row["constants"] = pulls_of(cal.get("parameters", []), truth, "cal ")
    return row


# ---- summaries --------------------------------------------------------------------------------
def _ks_uniform(p: Sequence[float]) -> float:
    from scipy import stats  # the KS test of p-values against U(0, 1)

    return float(stats.kstest(np.asarray(p, dtype=float), "uniform").pvalue) if p else math.nan


def _q(x: Sequence[float], q: float) -> float:
    return float(np.quantile(np.asarray(x, dtype=float), q)) if len(x) else math.nan


def _recommends(rec: str | None, term: str) -> bool:
    """Does the recommended spec hold ``term`` (term[:sensor[:axes]], axes matched loosely)?"""
    if not rec:
        return False
    want = term.split(":")
    for entry in rec.split(","):
        got = entry.split(":")
        if got[0] != want[0]:
            continue
        if len(want) > 1 and len(got) > 1 and got[1] != want[1]:
            continue
        if len(want) > 2 and len(got) > 2 and want[2] not in got[2]:
            continue
        return True
    return False


def _non_base(spec: str) -> list[str]:
    """The entries of a model spec that are not base terms."""
    base = ("bias:", "scale:", "misalignment:", "g_sensitivity:")
    return [x for x in spec.split(",") if x and not x.startswith(base)]


def _generic(text: str, e: dict[str, Any]) -> str:
    """``text`` with the effect's channel axis written i and its source axis j, so that
    sessions with different axes read alike (e.g. ``face_error:accel:i``)."""
    ax, src = e.get("axis"), e.get("source")
    if src:
        text = re.sub(rf"\b(force|rate) {src}\b", r"\1 j", text)
    if ax:
        text = re.sub(rf"(:|\b(?:accel|gyro)[ -]){ax}\b", r"\1i", text)
    return text


def _most(items: Sequence[str]) -> str:
    if not items:
        return "—"
    counts: dict[str, int] = {}
    for x in items:
        counts[x] = counts.get(x, 0) + 1
    best = max(counts, key=lambda k: counts[k])
    return f"{counts[best]}× {best}"


def summarise(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The numbers the tables print, per case (JSON-able)."""
    out: dict[str, Any] = {}
    by_case: dict[str, list[dict[str, Any]]] = {}
    for r in rows:
        by_case.setdefault(r["case"], []).append(r)
    order = [c for c in CASES if c in by_case] + [c for c in by_case if c not in CASES]
    for name in order:  # the cases in CASES's order, whatever the order of the lines
        rs = by_case[name]
        case = CASES.get(name)
        ok = [r for r in rs if "error" not in r]
        z = [r["rms_z"] for r in ok]
        p = [r["p"] for r in ok]
        verdicts = {v: sum(r["verdict"] == v for r in ok) for v in ("adequate", "missing_effect",
                                                                      "unexplained")}  # fmt: skip
        sm: dict[str, Any] = {
            "n": len(ok), "errors": len(rs) - len(ok), "rms_z_med": _q(z, 0.5),
            "rms_z_p10": _q(z, 0.1), "rms_z_p90": _q(z, 0.9),
            "chi2_dof_med": _q([r["chi2_dof"] for r in ok], 0.5),
            "flagged_5pc": float(np.mean([x < 0.05 for x in p])) if p else math.nan,
            "ks_p": _ks_uniform(p), "min_p": min(p) if p else math.nan, "verdicts": verdicts,
        }  # fmt: skip
        for sensor in ("accel", "gyro"):
            ratio = [r["floor"][sensor] / r["white_mean"][sensor] for r in ok
                     if sensor in r.get("floor", {}) and "white_mean" in r]  # fmt: skip
            sm[f"floor_ratio_{sensor}"] = _q(ratio, 0.5)
        if case is not None and case.kind != "control":
            truths = [{"effect": r["effect"], "constants": {}} for r in ok]
            if case.term is not None:
                sm["rec_hit"] = sum(
                    _recommends(r["recommended"], case.term(t))
                    for r, t in zip(ok, truths, strict=True)
                )
                in_group = [
                    any(_recommends(",".join(e["terms"]), case.term(t))
                        for e in r.get("equals", []))
                    for r, t in zip(ok, truths, strict=True)
                ]  # fmt: skip
                sm["eq_hit"] = sum(in_group)
                # named (recommended, or in a group of equals) and the expected term takes
                # RMS z down ≥ 3× to ≤ 1.5
                sm["falls_named"] = sum(
                    (g or _recommends(r["recommended"], case.term(t)))
                    and (a := r.get("rms_z_after_term")) is not None
                    and a <= 1.5 and 3 * a <= r.get("rms_z_before_term", r["rms_z"])
                    for r, t, g in zip(ok, truths, in_group, strict=True)
                )  # fmt: skip
            sm["single_term"] = sum(
                bool(r["recommended"]) and len(_non_base(r["recommended"])) == 1 for r in ok
            )
            sm["rec_any"] = sum(bool(r["recommended"]) for r in ok)
            if case.wrong:
                sm["rec_wrong"] = sum(
                    any(_recommends(r["recommended"], w) for w in case.wrong) for r in ok
                )
            sm["rec_most"] = _most(
                [_generic(r["recommended"], r["effect"]) for r in ok if r["recommended"]]
            )
            sm["top_most"] = _most(
                [_generic(f"{r['signals'][0]['sensor']} {r['signals'][0]['axis']}: "
                          f"{r['signals'][0]['signal']}", r["effect"]) for r in ok if r["signals"]]
            )  # fmt: skip
            if case.signal is not None:
                # the strongest unexplained signal, or (none) a signal in a group of equals
                sm["named_top"] = sum(
                    case.signal(r["signals"][0], t) if r["signals"]
                    else any(case.signal(sg, t) for e in r.get("equals", [])
                             for sg in e["signals"])
                    for r, t in zip(ok, truths, strict=True)
                )  # fmt: skip
            if case.names:
                sm["named_term"] = sum(
                    any(_recommends(lab, f"{n}:{r['effect']['sensor']}:{r['effect']['axis']}")
                        for lab in r.get("significant", []) for n in case.names)
                    for r in ok
                )  # fmt: skip
            after = [r.get("rms_z_after_rec") for r in ok]
            falls = [
                a is not None and a <= 1.5 and a * 3 <= r.get("rms_z_before_rec", r["rms_z"])
                for r, a in zip(ok, after, strict=True)
            ]
            sm["falls_3x_to_1_5"] = sum(falls) if case.kind == "catalogue" else None
            sm["after_rec_med"] = _q([a for a in after if a is not None], 0.5)
            sm["after_term_med"] = _q([r["rms_z_after_term"] for r in ok
                                       if r.get("rms_z_after_term") is not None], 0.5)  # fmt: skip
        if any("step_truth" in r for r in ok):
            sm["steps"] = step_stats(ok)
        if case is not None and case.plate:
            ratio, in10, in2s = [], [], []
            for r in ok:
                c = {x[0]: x for x in r.get("coef", [])}
                if "plate_tilt.east" not in c or "plate_tilt.north" not in c:
                    continue
                fe, fn = c["plate_tilt.east"][1], c["plate_tilt.north"][1]
                se = math.hypot(c["plate_tilt.east"][2], c["plate_tilt.north"][2]) / math.sqrt(2)
                mag, true = math.hypot(fe, fn), float(r["effect"]["tilt_rad"])
                ratio.append(mag / true)
                in10.append(abs(mag - true) <= 0.1 * true)
                in2s.append(abs(mag - true) <= 2 * se)
            sm["tilt_ratio_med"], sm["tilt_ratio_p10"] = _q(ratio, 0.5), _q(ratio, 0.1)
            sm["tilt_ratio_p90"] = _q(ratio, 0.9)
            sm["tilt_in10"], sm["tilt_in2s"], sm["tilt_n"] = sum(in10), sum(in2s), len(ratio)
        pulls: dict[str, dict[str, list[float]]] = {}
        sessions: dict[str, set[int]] = {}
        for r in ok:
            for nm, v, se, t in r.get("coef", []) + r.get("constants", []):
                pulls.setdefault(pull_group(nm), {}).setdefault(nm, []).append((v - t) / se)
                sessions.setdefault(pull_group(nm), set()).add(int(r["seed"]))
        sm["pulls"] = {
            g: {**pull_stats(members), "n": len(sessions[g])} for g, members in pulls.items()
        }
        out[name] = sm
    return out


def _f(x: Any, fmt: str = ".2f") -> str:
    return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:{fmt}}"


def tables(summary: dict[str, Any], pull_min_n: int = 1) -> str:
    """The summary as text tables, at most 100 columns wide."""
    lines: list[str] = []
    ctrl = [k for k in summary if CASES.get(k) is not None and CASES[k].kind == "control"]
    if ctrl:
        lines.append("== controls (nothing hidden): want median RMS z 0.8–1.25, ~5 % (≤ 10 %) "
                     "flagged, KS p not small")  # fmt: skip
        lines.append("   floor/white = the floor the session adds to a record mean beyond white")
        lines.append("   noise, over the white noise of a 10 s static mean; ≈ 0 on white data")
        lines.append(
            f"{'case':<9}{'n':>4}{'RMS z med':>10}{'p10–p90':>11}{'χ²/dof':>7}{'flag5%':>7}"
            f"{'KS p':>8}{'min p':>6}{'a/m/u':>9}{'floor/white a, g':>18}"
        )
        for k in ctrl:
            s = summary[k]
            v = s["verdicts"]
            vv = f"{v['adequate']}/{v['missing_effect']}/{v['unexplained']}"
            fl = f"{_f(s.get('floor_ratio_accel'), '.1f')}, {_f(s.get('floor_ratio_gyro'), '.1f')}"
            lines.append(
                f"{k:<9}{s['n']:>4}{_f(s['rms_z_med']):>10}"
                f"{_f(s['rms_z_p10']) + '–' + _f(s['rms_z_p90']):>11}{_f(s['chi2_dof_med']):>7}"
                f"{_f(s['flagged_5pc'], '.0%'):>7}{_f(s['ks_p'], '.2g'):>8}"
                f"{_f(s['min_p'], '.2g'):>6}{vv:>9}{fl:>18}"
            )
    eff = [k for k in summary if k not in ctrl]
    if eff:
        lines.append("")
        lines.append("== effects: a/m/u = verdicts adequate/missing_effect/unexplained; rec = the")
        lines.append("   expected term recommended; any = some term recommended; top = the right")
        lines.append("   top signal; →rec, →term = RMS z after adding the recommended/expected")
        lines.append("   term; fall = RMS z falls ≥ 3× to ≤ 1.5 after the recommended term;")
        lines.append("   sig = time_drift significant on the effect's channel (named a drift);")
        lines.append("   eq = the expected term in a group of equals; one = a single non-base")
        lines.append("   term recommended; fall* = named (rec or eq) and the expected term")
        lines.append("   takes RMS z down ≥ 3× to ≤ 1.5 (before on the yardstick it is tested")
        lines.append("   on: `model add`'s, without the turn angle of the axes it closes)")
        lines.append(f"{'case':<17}{'n':>3}{'a/m/u':>9}{'rec':>5}{'any':>5}{'top':>5}"
                     f"{'RMS z':>8}{'→rec':>7}{'→term':>7}{'fall':>6}{'sig':>5}"
                     f"{'eq':>4}{'one':>4}{'fall*':>6}")  # fmt: skip
        for k in eff:
            s = summary[k]
            v = s["verdicts"]
            vv = f"{v['adequate']}/{v['missing_effect']}/{v['unexplained']}"
            lines.append(
                f"{k:<17}{s['n']:>3}{vv:>9}{_f(s.get('rec_hit'), 'd'):>5}"
                f"{_f(s.get('rec_any'), 'd'):>5}{_f(s.get('named_top'), 'd'):>5}"
                f"{_f(s['rms_z_med']):>8}{_f(s.get('after_rec_med')):>7}"
                f"{_f(s.get('after_term_med')):>7}{_f(s.get('falls_3x_to_1_5'), 'd'):>6}"
                f"{_f(s.get('named_term'), 'd'):>5}{_f(s.get('eq_hit'), 'd'):>4}"
                f"{_f(s.get('single_term'), 'd'):>4}{_f(s.get('falls_named'), 'd'):>6}"
            )
    if eff:
        lines.append("")
        lines.append("== most frequent recommendation and top unexplained signal (i = the effect's")
        lines.append("   channel axis, j = its source axis; base terms left out of the spec)")
        for k in eff:
            s = summary[k]
            rec = re.sub(r"(bias|scale|misalignment|g_sensitivity):[a-z]+:xyz,?", "",
                         str(s.get("rec_most", "—")))  # fmt: skip
            lines.append(f"{k:<17}rec {rec[:78]}")
            lines.append(f"{'':<17}top {str(s.get('top_most', '—'))[:78]}")
    lines.extend(steps_table(summary))
    plate = [k for k in summary if CASES.get(k) is not None and CASES[k].plate]
    if plate:
        lines.append("")
        lines.append("== plate tilt (plate_tilt:accel added to base): |fit|/|truth|; within 10 %; "
                     "within 2σ")  # fmt: skip
        lines.append(f"{'case':<17}{'n':>4}{'ratio med':>11}{'p10–p90':>14}{'≤10%':>7}{'≤2σ':>7}")
        for k in plate:
            s = summary[k]
            lines.append(
                f"{k:<17}{s['tilt_n']:>4}{_f(s['tilt_ratio_med']):>11}"
                f"{_f(s['tilt_ratio_p10']) + '–' + _f(s['tilt_ratio_p90']):>14}"
                f"{s['tilt_in10']:>7}{s['tilt_in2s']:>7}"
            )
    wrong = [k for k in summary if summary[k].get("rec_wrong") is not None]
    if wrong:
        lines.append("")
        lines.append("== a wrong geometry recommended (a term the case does not hold)")
        for k in wrong:
            lines.append(f"{k:<17}{summary[k]['rec_wrong']:>3} of {summary[k]['n']}: "
                         f"{', '.join(CASES[k].wrong)}")  # fmt: skip
    lines.append("")
    lines.append("== pulls (fitted − truth)/σ: want sd 0.7–1.4 over ≥ 50 sessions; n = sessions,")
    lines.append("   k = coefficients pooled (a term's channels), sd range = smallest–largest sd")
    lines.append("   of one coefficient")
    lines.append(f"{'case':<15}{'coefficients':<27}{'n':>4}{'k':>3}{'mean':>7}{'sd':>7}"
                 f"{'sd range':>13}{'|·|>3':>7}")  # fmt: skip
    for k, s in summary.items():
        for nm, p in s["pulls"].items():
            if p["n"] < pull_min_n:
                continue
            rng = _f(p["sd_lo"]) + "–" + _f(p["sd_hi"]) if p["members"] > 1 else ""
            lines.append(
                f"{k[:14]:<15}{nm[:26]:<27}{p['n']:>4}{p['members']:>3}{_f(p['mean']):>7}"
                f"{_f(p['sd']):>7}{rng:>13}{_f(p['beyond3'], '.0%'):>7}"
            )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default="all", help=f"comma list or all: {', '.join(CASES)}")
    ap.add_argument("--sessions", type=int, default=10, help="sessions per case (default 10)")
    ap.add_argument("--seed0", type=int, default=1000, help="first seed (default 1000)")
    ap.add_argument("--out", type=Path, help="append one JSON line per session to this file")
    ap.add_argument("--report", type=Path, nargs="+", help="print tables from saved lines only")
    ap.add_argument("--pull-min-n", type=int, default=1, help="hide pulls over fewer sessions")
    a = ap.parse_args(argv)
    rows: list[dict[str, Any]] = []
    if a.report:
        unique: dict[tuple[str, int], dict[str, Any]] = {}
        for f in a.report:  # a session measured twice counts once: the later line wins
            for x in f.read_text(encoding="utf-8").splitlines():
                if x.strip():
                    r = json.loads(x)
                    unique[(r["case"], r["seed"])] = r
        rows = list(unique.values())
    else:
        names = list(CASES) if a.cases == "all" else a.cases.split(",")
        bad = [n for n in names if n not in CASES]
        if bad:
            print(f"unknown case(s) {', '.join(bad)}; one of {', '.join(CASES)}", file=sys.stderr)
            return 2
        with tempfile.TemporaryDirectory(prefix="yardstick-") as tmp:
            for name in names:
                for k in range(a.sessions):
                    row = run_session(CASES[name], a.seed0 + k, Path(tmp))
                    rows.append(row)
                    if a.out:
                        with a.out.open("a", encoding="utf-8") as f:
                            f.write(json.dumps(row) + "\n")
                    print(f"{name} seed {a.seed0 + k}: RMS z {_f(row.get('rms_z'))} "
                          f"{row.get('verdict', row.get('error'))}", file=sys.stderr)  # fmt: skip
    print(tables(summarise(rows), a.pull_min_n))
    return 0


if __name__ == "__main__":
    sys.exit(main())
