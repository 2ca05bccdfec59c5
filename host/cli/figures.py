"""The figures of the commands, read without the README: short titles, every axis labelled with
its unit, a legend for every mark, a word where a value is fitted exactly.

- the workbench (``model diagnose|add --plot``): :func:`compare_figure` — each record's residual
  in units of its σ, records in the order measured (across sittings: by start time), one scale
  before and after; :func:`suspect_figure` — those residuals against the added term's signal;
  :func:`write_plots` saves them.
- ``noise --plot``: :func:`noise_figure`, the Allan deviation per channel.
- ``thermal --plot``: :func:`thermal_figure`, bias against chip temperature per channel.

Each builder returns the matplotlib Figure (the tests read its titles, labels and legends);
the commands save and close it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from host.calib import thermal
from host.calib.thermal_fit import ThermalPoints
from host.cli import pyplot
from host.model import allan, recording
from host.model.dataset import Dataset
from host.model.design import term_columns
from host.model.fit import Fit
from host.model.signals import AXES, UNIT
from host.model.spec import ModelTerm, parse_model, short_spec
from host.session.records import STATIC_NAMES, TURN_NAMES

#: a title longer than this wraps or is cut in a figure a person glances at
TITLE_MAX = 60
#: the figures' resolution, dots per inch
DPI = 100
Z_LABEL = "z = residual / σ (no unit)"
_SHOWN = {"m/s^2": "m/s²", "deg/s": "°/s"}


def shown_unit(unit: str) -> str:
    """A unit as people read it: 'deg/s' -> '°/s', 'm/s^2' -> 'm/s²'."""
    return _SHOWN.get(unit, unit)


def _short(text: str, n: int = TITLE_MAX) -> str:
    return text if len(text) <= n else text[: n - 1] + "…"


# ---- the workbench ----------------------------------------------------------------------
def measurement_order(ds: Dataset, start_times: Mapping[str, str] | None = None) -> list[str]:
    """Record names in the order they were measured: by the records' start time (wall clock,
    ISO 8601: the order holds across sittings) when every record carries one, else by time since
    power-on when the records carry it, else the method's plan order (statics, then turns)."""
    plan = {n: i for i, n in enumerate((*STATIC_NAMES, *TURN_NAMES))}
    sigs = list(ds.signals)
    if start_times and all(s.name in start_times for s in sigs):
        sigs.sort(key=lambda s: (start_times[s.name], s.name))
    elif ds.time_known:
        sigs.sort(key=lambda s: float(s.t_s[0]))
    else:
        sigs.sort(key=lambda s: (plan.get(s.name, len(plan)), s.name))
    return [s.name for s in sigs]


def z_limit(fits: Sequence[Fit]) -> float:
    """One symmetric z scale for every panel of every fit (before and after look alike)."""
    zs = [abs(g.z) for f in fits for g in f.groups if math.isfinite(g.z)]
    return max(4.0, 1.1 * max(zs, default=0.0))


def model_words(fit: Fit) -> str:
    """The model in a title's few words: its short spec, or 'base + N terms' when long."""
    spec = short_spec(fit.model)
    parts = spec.split(",")
    if len(spec) <= 36:
        return spec.replace(",", ", ")
    return f"{parts[0]} + {len(parts) - 1} terms"


def compare_figure(ds: Dataset, fit: Fit, title: str, order: Sequence[str], lim: float) -> Any:
    """Per channel, each record's residual in units of its σ, records in ``order``; red where
    |z| > 3, a cross where the model passes exactly through the record (no residual to show)."""
    plt = pyplot()
    place = {n: i for i, n in enumerate(order)}
    fig, axs = plt.subplots(2, 3, figsize=(13, 7.5), squeeze=False)
    for si, sensor in enumerate(("accel", "gyro")):
        for a in range(3):
            ax = axs[si][a]
            name = f"{sensor} {AXES[a]}"
            gs = sorted((g for g in fit.groups if g.sensor == sensor and g.axis == AXES[a]),
                        key=lambda g: place.get(g.record, len(place)))  # fmt: skip
            ax.set_title(name, fontsize=10)
            if name in fit.untestable or not gs:
                msg = ("fitted exactly: the model passes\nthrough every record "
                       "(no degrees of freedom)" if gs else "no records")  # fmt: skip
                ax.text(0.5, 0.5, msg, ha="center", va="center", transform=ax.transAxes)
                ax.set_xticks([])
                ax.set_yticks([])
                continue
            zs = np.array([g.z for g in gs], dtype=float)
            exact = ~np.isfinite(zs)
            shown = np.where(exact, 0.0, zs)
            x = np.arange(len(gs))
            ok = np.abs(shown) <= 3
            if ok.any():
                ax.bar(x[ok], shown[ok], color="C0", label="|z| ≤ 3")
            if (~ok).any():
                ax.bar(x[~ok], shown[~ok], color="C3", label="|z| > 3: not explained")
            if exact.any():
                ax.plot(x[exact], np.zeros(int(exact.sum())), "kx", ms=7,
                        label="fitted exactly (no residual)")  # fmt: skip
            ax.axhline(3, color="k", lw=0.6, ls="--", label="±3 (3 σ)")
            ax.axhline(-3, color="k", lw=0.6, ls="--")
            ax.set_ylim(-lim, lim)
            ax.set_xticks(x)
            ax.set_xticklabels([g.record for g in gs], rotation=90, fontsize=7)
            ax.set_xlabel("record, in the order measured", fontsize=8)
            ax.set_ylabel(Z_LABEL, fontsize=8)
    handles: dict[str, Any] = {}
    for ax in axs.ravel():
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(lab, h)
    if handles:
        fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=4,
                   fontsize=8, frameon=False)  # fmt: skip
    fig.suptitle(_short(title), fontsize=11)
    fig.tight_layout(rect=(0, 0.05, 1, 0.96))
    return fig


def column_unit(sensor: str, param_unit: str) -> str:
    """The unit of a term's signal (its design column): the channel's unit over the parameter's
    (a gyro bias per °C: the column is in °C)."""
    u = UNIT[sensor]
    if param_unit == "1":
        return u
    if param_unit.startswith(u + "/"):
        return param_unit[len(u) + 1 :]
    if param_unit.startswith("1/"):
        return param_unit[2:].strip("()")
    return f"{u} per {param_unit}"


def suspect_signal(ds: Dataset, mt: ModelTerm, axis: int) -> tuple[np.ndarray, str, str]:
    """The signal (one value per row), its name and unit that ``mt``'s residuals are drawn
    against on channel ``axis``: the column of its first parameter on that axis; for a term
    whose parameters every channel shares (a lever arm, a plate tilt: one set of columns, each
    channel's rows holding its own regressors), the parameter that varies most on that
    channel's rows (a lever arm's offset along the axis itself moves it least)."""
    cols, _ = term_columns(ds, mt)
    units = mt.term.param_units(mt.sensor)
    k = len(mt.term.params)
    if not mt.term.shared:
        j = mt.axes.index(axis) * k
        return cols[:, j], mt.term.name, column_unit(mt.sensor, units[0])
    rows = [r for (ri, s, a), r in ds.rows_of.items() if s == mt.sensor and a == axis]
    on = np.concatenate(rows) if rows else np.arange(0)
    spread = [float(np.ptp(cols[on, j])) if len(on) else 0.0 for j in range(k)]
    j = int(np.argmax(spread))
    name = mt.term.name if k == 1 else f"{mt.term.name} {mt.term.params[j]}"
    return cols[:, j], name, column_unit(mt.sensor, units[j])


def suspect_figure(ds: Dataset, fits: Sequence[tuple[str, Fit]], spec: str, lim: float) -> Any:
    """Each record's residual (z) against the mean of the suspect term's signal over the
    record, before and after adding it: a line of points before, a flat cloud after."""
    plt = pyplot()
    mt = parse_model(spec)[0]
    # the term's axis that the data point at: the worst channel before it was added
    before = fits[0][1]

    def misfit(a: int) -> float:
        zs = [g.z for g in before.groups if g.sensor == mt.sensor and g.axis == AXES[a]]
        return sum(z**2 for z in zs if math.isfinite(z))

    axis = max(mt.axes, key=misfit)
    x, xname, xunit = suspect_signal(ds, mt, axis)
    channel = f"{mt.sensor} {AXES[axis]}"
    fig, axs = plt.subplots(1, len(fits), figsize=(6 * len(fits), 4.8), squeeze=False)
    for k, (tag, fit) in enumerate(fits):
        ax = axs[0][k]
        labels: list[tuple[float, float, str]] = []
        for gr in ds.groups:
            if gr.sensor != mt.sensor or gr.axis != axis:
                continue
            rec = ds.signals[gr.record]
            xv = float(np.mean(x[gr.rows]))
            if rec.kind == "turn" and gr.sensor == "gyro":
                xv /= max(float(ds.aggregators[gr.record].sum()), 1e-9)
            g = next(g for g in fit.groups if g.record == rec.name
                     and g.sensor == mt.sensor and g.axis == AXES[axis])  # fmt: skip
            exact = not math.isfinite(g.z)
            z = 0.0 if exact else g.z
            kind = "turn record" if rec.kind == "turn" else "static record"
            style = "kx" if exact else ("s" if rec.kind == "turn" else "o")
            color = "k" if exact else ("C1" if rec.kind == "turn" else "C0")
            ax.plot(xv, z, style, color=color, ms=6,
                    label="fitted exactly" if exact else kind)  # fmt: skip
            if abs(z) > 3:
                labels.append((xv, z, rec.name))
        # names only where it matters (|z| > 3), stacked where points fall together
        span = float(np.ptp([p[0] for p in labels])) if len(labels) > 1 else 1.0
        placed: list[tuple[float, float]] = []
        for xv, z, name in sorted(labels, key=lambda p: (p[0], p[1])):
            near = sum(1 for px, pz in placed if abs(px - xv) <= 0.03 * span and abs(pz - z) < 1)
            placed.append((xv, z))
            ax.annotate(name, (xv, z), xytext=(5, 2 + 9 * near), textcoords="offset points",
                        fontsize=7)  # fmt: skip
        ax.axhline(0, color="k", lw=0.5, label="z = 0: the model")
        ax.axhline(3, color="k", lw=0.6, ls="--", label="±3 (3 σ)")
        ax.axhline(-3, color="k", lw=0.6, ls="--")
        ax.set_ylim(-lim, lim)
        ax.set_xlabel(f"{xname} signal, mean over the record ({xunit})", fontsize=8)
        ax.set_ylabel(f"{channel}: {Z_LABEL}", fontsize=8)
        ax.set_title(f"{tag}: RMS z {fit.rms_z:.2f}", fontsize=10)
        h, lab = ax.get_legend_handles_labels()
        uniq = dict(zip(lab, h, strict=True))
        ax.legend(list(uniq.values()), list(uniq), fontsize=7, loc="best")
    fig.suptitle(_short(f"{channel} residuals against {mt.term.name}"), fontsize=11)
    fig.tight_layout()
    return fig


def write_plots(
    out_dir: str | Path, ds: Dataset, before: Fit, after: Fit | None, suspect: str | None,
    start_times: Mapping[str, str] | None = None,
) -> list[Path]:  # fmt: skip
    """PNG files ``compare_before.png`` (and ``compare_after.png``, ``suspect.png`` when a term
    is added) in ``out_dir`` (made if missing)."""
    plt = pyplot()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fits = [("before", before)] + ([("after", after)] if after is not None else [])
    order = measurement_order(ds, start_times)
    lim = z_limit([f for _, f in fits])
    paths: list[Path] = []
    for tag, fit in fits:
        if tag == "before":
            title = f"Before: {model_words(fit)} — RMS z {fit.rms_z:.2f}"
        else:
            title = f"After: + {suspect} — RMS z {fit.rms_z:.2f}"
        fig = compare_figure(ds, fit, title, order, lim)
        paths.append(out / f"compare_{tag}.png")
        fig.savefig(paths[-1], dpi=DPI)
        plt.close(fig)
    if suspect:
        fig = suspect_figure(ds, fits, suspect, lim)
        paths.append(out / "suspect.png")
        fig.savefig(paths[-1], dpi=DPI)
        plt.close(fig)
    return paths


# ---- noise ------------------------------------------------------------------------------
def noise_figure(an: recording.NoiseAnalysis, name: str) -> Any:
    """Log–log Allan deviation per channel: the data and its confidence band, each figure's
    line (labelled with the printed value), the square where it was read, and their sum."""
    plt = pyplot()
    fig, axs = plt.subplots(2, 3, figsize=(14, 8), squeeze=False)
    for ax, (chan, ch) in zip(axs.ravel(), an.channels.items(), strict=False):
        c = ch.curve
        unit = shown_unit(allan.UNITS[allan.sensor_of(chan)][1])
        assert c.lo is not None and c.hi is not None
        ax.fill_between(c.tau_s, np.sqrt(c.lo), np.sqrt(c.hi), color="C0", alpha=0.25,
                        label=f"{100 * an.ci:.0f} % interval")  # fmt: skip
        ax.loglog(c.tau_s, c.adev, "o", ms=3, color="C0", label="Allan deviation")
        tau = np.logspace(math.log10(c.tau_s[0]), math.log10(c.tau_s[-1]), 200)
        total = np.zeros_like(tau)
        read = False
        for k, q in enumerate(allan.QUANTITIES):
            f = ch.figures[q]
            if f.value is None:
                continue
            line = np.sqrt(allan.basis(tau)[:, k] * f.value**2)
            total += line**2
            v, u = recording.display_units(chan, q, f.value)
            ax.loglog(tau, line, "--", color=f"C{k + 1}",
                      label=f"{q.replace('_', ' ')} {v:.3g} {u}")  # fmt: skip
            if f.tau_s is not None:
                ax.plot([f.tau_s], [math.sqrt(allan.basis(np.array([f.tau_s]))[0, k]) * f.value],
                        "s", color=f"C{k + 1}", ms=7,
                        label=None if read else "where a figure is read")  # fmt: skip
                read = True
        ax.loglog(tau, np.sqrt(total), "-", color="k", lw=1, label="sum of the figures")
        ax.set_title(chan, fontsize=10)
        ax.set_xlabel("averaging time τ (s)", fontsize=8)
        ax.set_ylabel(f"Allan deviation ({unit})", fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(_short(f"{name}: Allan deviation"), fontsize=11)
    fig.tight_layout()
    return fig


# ---- thermal ----------------------------------------------------------------------------
def thermal_figure(cal: thermal.ThermalCalibration, pts: ThermalPoints) -> Any:
    """Each channel's bias against temperature: the window means (less their attitude's
    offset), the fitted curve and its simultaneous 95 % band, T_ref and the valid range."""
    plt = pyplot()
    fig, axs = plt.subplots(2, 3, figsize=(14, 8), squeeze=False)
    temps = np.linspace(cal.t_min_c, cal.t_max_c, 200)
    for j, (ax, name) in enumerate(zip(axs.ravel(), thermal.CHANNELS, strict=True)):
        ch = cal.channels[name]
        y = pts.values[:, j]
        # each attitude's offset: the mean of its points less the curve there
        resid0 = y - ch.delta(pts.temp_c, cal.t_ref_c)
        offs = np.array([resid0[pts.group == g].mean() for g in range(len(pts.attitudes))])
        ax.plot(pts.temp_c, y - offs[pts.group], ".", ms=3, color="C0",
                label="window means (less the attitude's offset)")  # fmt: skip
        curve = ch.delta(temps, cal.t_ref_c)
        band = ch.band(temps, cal.t_ref_c)
        ax.fill_between(temps, curve - band, curve + band, color="C1", alpha=0.3,
                        label=f"{100 * thermal.BAND_LEVEL:.0f} % band")  # fmt: skip
        ax.plot(temps, curve, "-", color="C1", label=f"fit, order {ch.order}")
        ax.axvline(cal.t_ref_c, color="k", lw=0.8, ls=":", label=f"T_ref {cal.t_ref_c:.1f} °C")
        ax.set_title(f"{name}: order {ch.order}", fontsize=10)
        ax.set_xlabel("chip temperature (°C)", fontsize=8)
        ax.set_ylabel(f"bias(T) − bias(T_ref) ({shown_unit(ch.unit)})", fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(_short(f"{cal.serial}: bias against temperature, "
                        f"{cal.t_min_c:.0f}–{cal.t_max_c:.0f} °C"), fontsize=11)  # fmt: skip
    fig.tight_layout()
    return fig
