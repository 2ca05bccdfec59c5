"""The plots read at a glance (issue 27): short titles, axis labels with units, a legend for
every mark, a word where a value is fitted exactly, records in the order measured. Read from
the matplotlib figure objects the commands save."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from host.bench.plan import write_session  # noqa: E402
from host.cli import figures  # noqa: E402
from host.model.dataset import load_dataset  # noqa: E402
from host.model.spec import parse_model  # noqa: E402
from host.workbench.ladder import add_term  # noqa: E402
from host.workbench.scenarios import hidden_effect_case  # noqa: E402

#: a unit in an axis label: in parentheses at its end, or "(no unit)"
UNIT = re.compile(r"\((no unit|[^()]*[a-zA-Z°µ%²][^()]*|°C|s)\)$")


@pytest.fixture(scope="module")
def case(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    d = tmp_path_factory.mktemp("fig")
    c = hidden_effect_case("temperature", 2)
    write_session(d, "F7", dict(c.records))
    return d, c.term


def check_figure(fig: object, *, categorical_x: bool = False) -> None:
    """The rules every figure keeps."""
    title = fig._suptitle.get_text()  # type: ignore[attr-defined]
    assert 0 < len(title) <= figures.TITLE_MAX, title
    legend_texts = {t.get_text() for lg in fig.legends for t in lg.get_texts()}  # type: ignore[attr-defined]
    for ax in fig.axes:  # type: ignore[attr-defined]
        if not ax.has_data():
            continue  # a panel that says in words why it is empty
        assert len(ax.get_title()) <= 30, ax.get_title()
        assert UNIT.search(ax.get_ylabel()), ax.get_ylabel()
        assert categorical_x or UNIT.search(ax.get_xlabel()), ax.get_xlabel()
        assert ax.get_xlabel()
        shown = legend_texts | ({t.get_text() for t in ax.get_legend().get_texts()}
                                if ax.get_legend() else set())  # fmt: skip
        marks = [a.get_label() for a in (*ax.lines, *ax.containers, *ax.collections)
                 if not a.get_label().startswith("_")]  # fmt: skip
        assert marks, "every mark is labelled"
        assert set(marks) <= shown, set(marks) - shown
        unlabelled = [a for a in ax.lines if a.get_label().startswith("_") and len(a.get_xdata())
                      and not _is_twin_of_a_labelled_line(a, ax)]  # fmt: skip
        assert unlabelled == [], [a.get_label() for a in unlabelled]


def _is_twin_of_a_labelled_line(line: object, ax: object) -> bool:
    """The lower ±3 line, or a further marker of a kind already in the legend."""
    style = (line.get_linestyle(), line.get_marker())  # type: ignore[attr-defined]
    return any((o.get_linestyle(), o.get_marker()) == style
               and not o.get_label().startswith("_") for o in ax.lines)  # type: ignore[attr-defined]  # fmt: skip


@pytest.mark.slow
def test_the_workbench_figures_read_at_a_glance(case: tuple[Path, str]) -> None:
    d, term = case
    ds = load_dataset(d)
    a = add_term(ds, parse_model("base"), term)
    lim = figures.z_limit([a.before, a.after])
    order = figures.measurement_order(ds)
    before = figures.compare_figure(ds, a.before, "Before: base — RMS z 5.00", order, lim)
    check_figure(before, categorical_x=True)
    # the records along x in the order measured
    ax = before.axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == order
    suspect = figures.suspect_figure(ds, [("before", a.before), ("after", a.after)], term, lim)
    check_figure(suspect)
    assert "°C" in suspect.axes[0].get_xlabel()  # a temperature term's signal is in °C


@pytest.mark.slow
def test_a_channel_fitted_exactly_says_so(case: tuple[Path, str]) -> None:
    """A channel whose records leave no degrees of freedom (the fit passes through each) has no
    residual to show: its panel says so in words instead of standing empty."""
    import dataclasses

    d, _ = case
    ds = load_dataset(d)
    fit = add_term(ds, parse_model("base"), "time_drift:gyro").after
    exact = dataclasses.replace(fit, channels=tuple(
        dataclasses.replace(c, dof_records=0) if c.channel == "gyro z" else c
        for c in fit.channels))  # fmt: skip
    assert exact.untestable == ("gyro z",)
    fig = figures.compare_figure(ds, exact, "t", figures.measurement_order(ds), 5.0)
    panel = fig.axes[5]
    assert panel.get_title() == "gyro z"
    assert "fitted exactly" in " ".join(t.get_text() for t in panel.texts)
    check_figure(fig, categorical_x=True)


def test_records_follow_their_start_time_across_sittings(case: tuple[Path, str]) -> None:
    """Two sittings each count time from their own power-on; the start times (wall clock) put
    the second sitting's records after the first's."""
    d, _ = case
    ds = load_dataset(d)
    names = [s.name for s in ds.signals]
    later_sitting = {"x_up", "x_dn"}  # measured again the next day
    times = {n: ("2026-11-27T09:00:00" if n in later_sitting else f"2026-11-26T10:{i:02d}:00")
             for i, n in enumerate(figures.measurement_order(ds))}  # fmt: skip
    order = figures.measurement_order(ds, times)
    assert set(order[-2:]) == later_sitting and set(order) == set(names)


@pytest.mark.slow
def test_the_noise_figure_reads_at_a_glance() -> None:
    from host.bench.noise import NoiseTruth, static_noise
    from host.model import recording

    t, x, temp = static_noise(NoiseTruth.mpu6000(), 600.0, np.random.default_rng(3))
    fig = figures.noise_figure(recording.analyse(t, x, temp), "U1_x_up.txt")
    check_figure(fig)
    assert "°/s" in fig.axes[3].get_ylabel() and "deg" not in fig.axes[3].get_ylabel()


@pytest.mark.slow
def test_the_thermal_figure_reads_at_a_glance() -> None:
    from host.bench.plan import simulate_thermal
    from host.calib import thermal_fit
    from tests.host.calib.test_thermal import CHAMBER, PLAN, TRUTH

    recs = simulate_thermal(TRUTH, CHAMBER, PLAN, seed=4)
    cal, pts = thermal_fit.fit_thermal(list(recs.values()), "T1")
    fig = figures.thermal_figure(cal, pts)
    check_figure(fig)
    assert "°C" in fig.axes[0].get_xlabel() and "degC" not in fig._suptitle.get_text()


@pytest.fixture(scope="module")
def lever_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An independent session (tests/independent) whose sensor sits off the cube's centre."""
    from tests.independent.simulate import SessionSpec
    from tests.independent.simulate import write_session as write_independent

    d = tmp_path_factory.mktemp("lever")
    write_independent(d, SessionSpec(seed=1003, effect="lever_arm"))
    return d


def test_every_suspect_has_a_signal_on_every_axis(lever_session: Path) -> None:
    """A suspect's signal on each of its channels, for every term of the catalogue: a term
    whose parameters every channel shares (a lever arm) has one set of columns, read on the
    channel's own rows (the first parameter of axis y or z was read past its columns: the
    IndexError of issue 39 when the top suspect was lever_arm:accel:xyz)."""
    from host.model.catalogue import CATALOGUE
    from host.model.spec import ModelTerm

    ds = load_dataset(lever_session)
    for t in CATALOGUE.values():
        for sensor in t.sensors:
            mt = ModelTerm(t, sensor, (0, 1, 2))
            for axis in range(3):
                x, name, unit = figures.suspect_signal(ds, mt, axis)
                assert x.shape == (ds.n_rows,) and np.all(np.isfinite(x)), (mt.label, axis)
                assert name.startswith(t.name) and unit, (mt.label, axis)
    # the lever arm: on each channel a parameter that moves it (an offset along the channel's
    # own axis is not one: the turns about the other axes see it)
    lever = ModelTerm(CATALOGUE["lever_arm"], "accel", (0, 1, 2))
    for axis in range(3):
        _, name, _ = figures.suspect_signal(ds, lever, axis)
        assert not name.endswith(" " + lever.term.params[axis]), name


def _worst_on(fit: object, sensor: str, axis: str) -> object:
    """``fit`` whose channel ``sensor axis`` misfits most (the other channels' z shrunk)."""
    import dataclasses

    groups = tuple(g if (g.sensor, g.axis) == (sensor, axis) else dataclasses.replace(g, z=0.0)
                   for g in fit.groups)  # type: ignore[attr-defined]  # fmt: skip
    return dataclasses.replace(fit, groups=groups)  # type: ignore[type-var]


@pytest.mark.slow
def test_the_lever_arm_suspect_is_drawn_on_every_channel(lever_session: Path) -> None:
    ds = load_dataset(lever_session)
    a = add_term(ds, parse_model("base"), "lever_arm:accel")
    for axis in "xyz":
        before = _worst_on(a.before, "accel", axis)
        fig = figures.suspect_figure(ds, [("before", before), ("after", a.after)],  # type: ignore[list-item]
                                     "lever_arm:accel:xyz", 5.0)  # fmt: skip
        check_figure(fig)
        assert f"accel {axis}" in fig._suptitle.get_text()


REAL = Path(__file__).resolve().parents[4] / "shared" / "data" / "imucal-example"


def _diagnosis_sessions(root: Path) -> list[tuple[Path, str]]:
    """The sessions the diagnosis tests read (tests/host/workbench/test_verdict.py): each
    hidden-effect demo, independent sessions with a scale asymmetry and a lever arm, and
    imucal's real session (with the plate's tilt in, its top suspect is the lever arm)."""
    from tests.independent.simulate import SessionSpec
    from tests.independent.simulate import write_session as write_independent

    out = []
    for effect in ("temperature", "drift", "asymmetry", "warmup", "none"):
        d = root / effect
        write_session(d, "F7", dict(hidden_effect_case(effect, 0).records))
        out.append((d, "base"))
    for seed, effect in ((4000, "scale_asymmetry"), (1003, "lever_arm")):
        d = root / effect
        write_independent(d, SessionSpec(seed=seed, effect=effect))
        out.append((d, "base"))
    if REAL.is_dir():
        out += [(REAL, "base"), (REAL, "base,plate_tilt:accel")]
    return out


@pytest.mark.timeout(300)  # ~50 s of CPU idle; timed out at 120 s on a loaded machine
@pytest.mark.slow
def test_diagnose_plot_draws_on_every_session_of_the_diagnosis_tests(tmp_path: Path) -> None:
    from tests.host.cli.cli_run import run

    for k, (d, model) in enumerate(_diagnosis_sessions(tmp_path / "sessions")):
        plots = tmp_path / f"plots{k}"
        rc, out, err = run(["model", "diagnose", str(d), "--brief", "--model", model,
                            "--plot", str(plots)])  # fmt: skip
        assert rc == 0, (d, model, err)
        drawn = {p.name for p in plots.iterdir()}
        assert "compare_before.png" in drawn, (d, drawn)
        if "  try: python3 -m host model add" in out:
            assert {"compare_after.png", "suspect.png"} <= drawn, (d, model, drawn)
