"""The QC page's charts as inline SVG (:func:`svg_chart`), a pure function of the points: the
time of each calibration on x (dates, or dates and times when they fall within two days), the
parameter in its unit on y, both axes titled; a trend's ± U band (95 %) and a control chart's
centre line and ±1/2/3 σ limits, the y range holding every point, band and limit drawn."""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime

import numpy as np

from host.session.method import UNITS

#: the chart's size in SVG units (drawn at most this wide, narrower on a phone)
W, H = 520, 230
#: the frame's margins: left (y ticks and title), right (limit names), top (title), bottom
LEFT, RIGHT, TOP, BOTTOM = 78, 40, 26, 50
X_TITLE = "calibrated (UTC)"


def _e(s: object) -> str:
    return html.escape(str(s))


def _g(v: float, digits: int = 3) -> str:
    return "—" if not math.isfinite(v) else f"{v:.{digits}g}"


def param_unit(name: str) -> str:
    """The unit of an archived parameter as the page writes it (method.md §7): ``1`` for a
    relative (dimensionless) scale error, ``?`` for a name the method does not list."""
    unit = UNITS.get(name)
    return "?" if unit is None else (unit or "1")


def y_title(name: str) -> str:
    """A y axis title: the parameter and its unit, e.g. ``A0x (m/s²)``."""
    return f"{name} ({param_unit(name)})"


def _seconds(times: Sequence[str]) -> np.ndarray:
    """UTC ISO 8601 texts as POSIX seconds (NaN where one does not parse)."""
    out = []
    for t in times:
        try:
            d = datetime.fromisoformat(t.replace("Z", "+00:00"))
        except ValueError:
            out.append(math.nan)
            continue
        out.append((d if d.tzinfo else d.replace(tzinfo=UTC)).timestamp())
    return np.asarray(out, dtype=np.float64)


def _time_label(s: float, span_s: float) -> str:
    d = datetime.fromtimestamp(s, tz=UTC)
    return d.strftime("%m-%d %H:%M") if span_s < 2 * 86400 else d.strftime("%Y-%m-%d")


@dataclass(frozen=True)
class _Frame:
    """Where values and times are drawn: x from ``t0``..``t1`` (s), y from ``lo``..``hi``."""

    t0: float
    t1: float
    lo: float
    hi: float

    def px(self, t: float) -> float:
        return LEFT + (W - LEFT - RIGHT) * (t - self.t0) / (self.t1 - self.t0)

    def py(self, v: float) -> float:
        return H - BOTTOM - (H - TOP - BOTTOM) * (v - self.lo) / (self.hi - self.lo)


def _y_range(v: np.ndarray, u: np.ndarray, limits: Sequence[float]) -> tuple[float, float]:
    """The y range holding every point, its band and every limit, with a margin of 5 %."""
    ends = [x for x in (*(v - u), *(v + u), *limits) if math.isfinite(x)]
    lo, hi = (min(ends), max(ends)) if ends else (0.0, 1.0)
    if not hi > lo:  # one value: a range around it, of its own size
        half = abs(lo) * 1e-3 or 1.0
        lo, hi = lo - half, hi + half
    m = 0.05 * (hi - lo)
    return lo - m, hi + m


def _x_range(t: np.ndarray) -> tuple[np.ndarray, float, float, bool]:
    """The times (s; by order where they do not parse or are all one), their range and
    whether they are times."""
    if t.size == 0 or not np.all(np.isfinite(t)) or not t.max() > t.min():
        t = np.arange(t.size, dtype=np.float64)
        return t, -0.5, max(t.size - 0.5, 0.5), False
    m = 0.04 * (t.max() - t.min())
    return t, float(t.min() - m), float(t.max() + m), True


def nice_ticks(lo: float, hi: float, n: int = 4) -> list[float]:
    """Round values (steps of 1, 2, 2.5 or 5 × 10ᵏ) inside ``lo``..``hi``, about ``n``."""
    raw = (hi - lo) / n
    mag = 10.0 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1.0, 2.0, 2.5, 5.0, 10.0) if m * mag >= raw)
    ks = range(math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9) + 1)
    return [min(max(k * step, lo), hi) for k in ks]  # k·step, not summed steps: no drift


def _tick_text(v: float, ticks: Sequence[float]) -> str:
    """A tick's value with the digits that tell the ticks apart."""
    step = abs(ticks[1] - ticks[0]) if len(ticks) > 1 else abs(v) or 1.0
    big = max(abs(x) for x in ticks) or step
    digits = max(1, math.ceil(math.log10(big / step)) + 2)
    return f"{0.0 if abs(v) < step * 1e-6 else v:.{digits}g}"


def _axes(f: _Frame, times_ok: bool, t: np.ndarray, name: str) -> list[str]:
    """The frame, the ticks on both axes and the two axis titles."""
    x0, x1, y0, y1 = LEFT, W - RIGHT, TOP, H - BOTTOM
    parts = [f'<rect x="{x0}" y="{y0}" width="{x1 - x0}" height="{y1 - y0}" class="frame"/>']
    ticks = nice_ticks(f.lo, f.hi)
    for v in ticks:
        yy = f.py(v)
        parts.append(f'<line x1="{x0 - 3}" x2="{x0}" y1="{yy:.1f}" y2="{yy:.1f}" class="tick"/>'
                     f'<text x="{x0 - 5}" y="{yy + 3:.1f}" class="a ty">'
                     f"{_e(_tick_text(v, ticks))}</text>")  # fmt: skip
    if times_ok and t.size:
        span = float(t.max() - t.min())
        for s in np.unique(np.linspace(t.min(), t.max(), min(3, t.size))):
            parts.append(f'<text x="{f.px(float(s)):.1f}" y="{y1 + 16}" class="a tx">'
                         f"{_e(_time_label(float(s), span))}</text>")  # fmt: skip
    x_title = X_TITLE if times_ok else "calibration (in time order)"
    parts.append(f'<text x="{(x0 + x1) / 2:.0f}" y="{H - 9}" class="xt">{_e(x_title)}</text>')
    parts.append(f'<text transform="translate(15 {(y0 + y1) / 2:.0f}) rotate(-90)" class="yt">'
                 f"{_e(y_title(name))}</text>")  # fmt: skip
    return parts


def _limits(f: _Frame, centre: float, sigma: float) -> list[str]:
    """The centre line and ±1/2/3 σ, each named at the right edge (centre and ±3 σ)."""
    parts = []
    for k, cls in ((0, "cl"), (1, "s1"), (-1, "s1"), (2, "s2"), (-2, "s2"), (3, "s3"),
                   (-3, "s3")):  # fmt: skip
        yy = f.py(centre + k * sigma)
        parts.append(f'<line x1="{LEFT}" x2="{W - RIGHT}" y1="{yy:.1f}" y2="{yy:.1f}" '
                     f'class="{cls}"/>')  # fmt: skip
        if k in (0, 3, -3):
            name = {0: "CL", 3: "UCL", -3: "LCL"}[k]
            parts.append(f'<text x="{W - RIGHT + 3}" y="{yy + 3:.1f}" class="a">{name}</text>')
    return parts


def _band(f: _Frame, t: np.ndarray, v: np.ndarray, u: np.ndarray) -> list[str]:
    """The ± U band through the points (a polygon) and each point's ± U bar."""
    ok = np.isfinite(v) & (u > 0)
    if not ok.any():
        return []
    tvu = list(zip(t[ok].tolist(), v[ok].tolist(), u[ok].tolist(), strict=True))
    up = [f"{f.px(a):.1f},{f.py(b + c):.1f}" for a, b, c in tvu]
    dn = [f"{f.px(a):.1f},{f.py(b - c):.1f}" for a, b, c in tvu]
    parts = [f'<polygon points="{" ".join(up + dn[::-1])}" class="band"/>']
    for a, b, c in tvu:
        x = f.px(float(a))
        parts.append(f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{f.py(float(b - c)):.1f}" '
                     f'y2="{f.py(float(b + c)):.1f}" class="err"/>')  # fmt: skip
    return parts


def _points(
    f: _Frame, t: np.ndarray, v: np.ndarray, marked: Sequence[bool] | None,
    labels: Sequence[str] | None,
) -> list[str]:  # fmt: skip
    """The line through the points and the points (``marked`` red, ``labels`` as tooltips)."""
    pts = [(f.px(a), f.py(b), i) for i, (a, b) in enumerate(zip(t.tolist(), v.tolist(),
           strict=True)) if math.isfinite(b)]  # fmt: skip
    parts = []
    if len(pts) > 1:
        path = " ".join(f"{x:.1f},{yy:.1f}" for x, yy, _ in pts)
        parts.append(f'<polyline points="{path}" class="line"/>')
    for x, yy, i in pts:
        cls = "pt bad" if marked is not None and marked[i] else "pt"
        tip = f"<title>{_e(labels[i])}</title>" if labels is not None else ""
        parts.append(f'<circle cx="{x:.1f}" cy="{yy:.1f}" r="3" class="{cls}">{tip}</circle>')
    return parts


def svg_chart(
    title: str,
    name: str,
    y: Sequence[float],
    times: Sequence[str],
    *,
    u: Sequence[float] | None = None,
    centre: float = math.nan,
    sigma: float = math.nan,
    marked: Sequence[bool] | None = None,
    labels: Sequence[str] | None = None,
) -> str:
    """An inline SVG of parameter ``name``'s values ``y`` (its unit: :func:`param_unit`) at
    ``times`` (UTC ISO 8601, in order), titled ``title``. ``u``: each value's expanded
    uncertainty U (95 %, its unit), drawn as the ± U band; ``centre``/``sigma`` finite: the centre
    line and the ±1/2/3 σ limits; ``marked`` points (a rule fired) red; ``labels`` tooltips."""
    v = np.asarray(y, dtype=np.float64)
    half = np.zeros_like(v) if u is None else np.nan_to_num(np.asarray(u, np.float64))
    limits = [centre + k * sigma for k in (-3, 3)] if math.isfinite(centre + sigma) else []
    t, t0, t1, times_ok = _x_range(_seconds(times))
    f = _Frame(t0, t1, *_y_range(v, half, [centre, *limits] if limits else []))
    parts = [
        f'<svg class="chart" xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" '
        f'viewBox="0 0 {W} {H}" role="img" aria-label="{_e(title)}">',
        f'<text x="{LEFT}" y="17" class="t">{_e(title)}</text>',
        *_axes(f, times_ok, t, name),
        *(_limits(f, centre, sigma) if limits else []),
        *_band(f, t, v, half),
        *_points(f, t, v, marked, labels),
    ]
    if u is not None:
        parts.append(f'<text x="{W - RIGHT}" y="17" class="a legend">band: ± U (95 %)</text>')
    parts.append("</svg>")
    return "".join(parts)
