"""The QC page's charts (host/archive/charts.py) read from their SVG: both axes titled, the
parameter's unit on y, the calibrations placed by their time on x, the ± U band of a trend
drawn at twice the σ, and a control chart's limits and points inside the plotted range — also
for a chart whose points are all one value (issue 45: both ticks read 0.108, the limit line
fell below the points)."""

from __future__ import annotations

import math
import re

import pytest

from host.archive.charts import BOTTOM, LEFT, RIGHT, TOP, H, W, nice_ticks, param_unit, svg_chart

DAYS = ["2026-01-01T08:00:00.000000Z", "2026-01-02T08:00:00.000000Z",
        "2026-01-05T08:00:00.000000Z"]  # fmt: skip


def _ys(svg: str, cls: str) -> list[float]:
    return [float(y) for y in re.findall(rf'<line [^>]*y1="([-\d.]+)"[^>]*class="{cls}"', svg)]


def _points(svg: str) -> list[tuple[float, float]]:
    return [(float(x), float(y)) for x, y in re.findall(r'<circle cx="([-\d.]+)" cy="([-\d.]+)"',
                                                         svg)]  # fmt: skip


def _texts(svg: str, cls: str) -> list[str]:
    return re.findall(rf'<text [^>]*class="{cls}"[^>]*>([^<]*)</text>', svg)


def test_a_chart_has_a_point_per_value_and_marks_the_signals() -> None:
    svg = svg_chart("B1 · <A0x>", "A0x", [1.0, 2.0, float("nan"), 1.5], [*DAYS, DAYS[2]],
                    centre=1.5, sigma=0.2, marked=[False, True, False, False],
                    labels=["a", "b", "c", "d"])  # fmt: skip
    assert svg.count("<circle") == 3  # the NaN is left out
    assert svg.count('class="pt bad"') == 1
    assert "&lt;A0x&gt;" in svg and "<A0x>" not in svg
    assert len(_ys(svg, "cl")) == 1 and len(_ys(svg, "s3")) == 2 and len(_ys(svg, "s1")) == 2
    ys = [y for _, y in _points(svg)]
    assert ys[1] < ys[2] < ys[0]  # higher values are drawn higher (smaller y)


@pytest.mark.parametrize("name", ["A0x", "G0z", "Gxx", "GAyz", "Gstdx"])
def test_both_axes_are_titled_and_y_carries_the_unit(name: str) -> None:
    svg = svg_chart("B1", name, [0.1, 0.2, 0.15], DAYS)
    assert _texts(svg, "xt") == ["calibrated (UTC)"]
    unit = {"A0x": "m/s²", "G0z": "°/s", "Gxx": "1", "GAyz": "(°/s)/g", "Gstdx": "°/s"}[name]
    assert param_unit(name) == unit
    assert _texts(svg, "yt") == [f"{name} ({unit})"]


def test_points_stand_at_their_times_and_the_ticks_are_dates() -> None:
    svg = svg_chart("B1", "A0x", [0.1, 0.2, 0.15], DAYS)
    (x0, _), (x1, _), (x2, _) = _points(svg)
    # 1 day then 3 days apart: the gaps on x in that ratio, not evenly spread by order
    assert (x2 - x1) / (x1 - x0) == pytest.approx(3.0, rel=1e-2)
    assert LEFT <= x0 < x1 < x2 <= W - RIGHT
    ticks = _texts(svg, "a tx")
    assert ticks[0] == "2026-01-01" and ticks[-1] == "2026-01-05"
    # within two days, the ticks name the time of day too
    close = svg_chart("B1", "A0x", [0.1, 0.2], ["2026-01-01T08:00:00Z", "2026-01-01T10:30:00Z"])
    assert _texts(close, "a tx") == ["01-01 08:00", "01-01 10:30"]


def test_without_times_the_axis_says_it_is_the_order() -> None:
    svg = svg_chart("B1", "A0x", [0.1, 0.2], ["?", "?"])
    assert _texts(svg, "xt") == ["calibration (in time order)"] and _texts(svg, "a tx") == []


def _value_to_y(svg: str) -> tuple[float, float]:
    """The chart's y = a + b·value, from its tick labels and their lines."""
    ticks = re.findall(r'y1="([-\d.]+)"[^>]*class="tick"/><text [^>]*class="a ty">([^<]*)<', svg)
    (y0, v0), (y1, v1) = [(float(y), float(v)) for y, v in (ticks[0], ticks[-1])]
    b = (y1 - y0) / (v1 - v0)
    return y0 - b * v0, b


def test_a_trend_draws_plus_minus_u_as_given() -> None:
    values, us = [0.10, 0.14, 0.12], [0.008, 0.020, 0.004]
    svg = svg_chart("U17 · A0x", "A0x", values, DAYS, u=us)
    a, b = _value_to_y(svg)
    bars = re.findall(r'y1="([-\d.]+)" y2="([-\d.]+)" class="err"', svg)
    assert len(bars) == 3 and "<polygon" in svg and "band: ± U (95 %)" in svg
    for (lo, hi), v, u in zip(bars, values, us, strict=True):
        assert float(lo) == pytest.approx(a + b * (v - u), abs=0.15)
        assert float(hi) == pytest.approx(a + b * (v + u), abs=0.15)


def test_a_trend_points_u_is_the_certificates() -> None:
    """A trend's U is the certificate's: 2σ for a σ from the noise model alone, Student's t
    at 95.45 % on the σ's dof where it is estimated (3.31σ on 3 dof)."""
    from scipy import stats

    from host.archive.checks import TrendPoint

    exact = TrendPoint("2026-01-01T00:00:00Z", "B1", 0.1, 0.01)
    few = TrendPoint("2026-01-01T00:00:00Z", "B1", 0.1, 0.01, 3.0)
    assert exact.expanded == pytest.approx(0.02)
    k3 = stats.t.isf((1 - math.erf(2**0.5)) / 2, 3)
    assert few.expanded == pytest.approx(0.01 * k3) and 3.3 < k3 < 3.32


@pytest.mark.parametrize(
    "values, centre, sigma",
    [
        ([0.108, 0.108, 0.108], 0.108, 0.0),  # every session the same (issue 45's chart)
        ([0.0, 0.01, 0.02, 0.5], 0.01, 0.004),  # a point far outside the limits
        ([1.0, 1.001, 0.999], 1.0, 0.05),  # limits far outside the points
    ],
)
def test_limits_and_points_lie_inside_the_plotted_range(
    values: list[float], centre: float, sigma: float
) -> None:
    svg = svg_chart("B1 · A0x", "A0x", values, DAYS + DAYS[:1] if len(values) > 3 else DAYS,
                    centre=centre, sigma=sigma)  # fmt: skip
    lines = _ys(svg, "cl") + _ys(svg, "s3") + _ys(svg, "s2")
    for y in lines + [y for _, y in _points(svg)]:
        assert TOP <= y <= H - BOTTOM
    ticks = _texts(svg, "a ty")
    assert len(ticks) >= 2 and len(set(ticks)) == len(ticks)  # distinct ticks, never one value
    a, b = _value_to_y(svg)
    assert b < 0  # higher values higher up
    for v, (_, y) in zip(values, _points(svg), strict=True):
        assert y == pytest.approx(a + b * v, abs=0.15)  # each point where its value is
    ucl = min(_ys(svg, "s3"))
    assert ucl == pytest.approx(a + b * (centre + 3 * sigma), abs=0.15)


@pytest.mark.parametrize("lo, hi", [(0.0, 1.0), (-0.013, 0.017), (0.1079, 0.1081), (-3e5, 2e5)])
def test_ticks_are_round_and_inside(lo: float, hi: float) -> None:
    ticks = nice_ticks(lo, hi)
    assert 3 <= len(ticks) <= 9 and all(lo <= t <= hi for t in ticks)
    steps = {round((b - a) / (hi - lo), 9) for a, b in zip(ticks, ticks[1:], strict=False)}
    assert len(steps) == 1
