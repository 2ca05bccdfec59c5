"""A sensor model is a list of named physical terms: the :class:`Term` type and the decorators
that make one from a column function (:func:`term`, :func:`nonlinear_term`).

Each :class:`Term` carries its physics (docstring), the sensor it acts on ("accel"/"gyro"), its
parameters with units and a function building its columns of the design matrix from the
records' reference signals (:class:`~host.model.signals.RecordSignals`). Terms nonlinear in
their parameters (``Term.value``) are linearised around the current estimate (numerical
Jacobian) and the fit iterated (Gauss-Newton). The built-in terms: :mod:`host.model.catalogue`.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from host.errors import UserError
from host.model.signals import AXES, SENSORS, UNIT, RecordSignals

# ---- terms ----------------------------------------------------------------------------------
ColumnFn = Callable[[RecordSignals, str, int], np.ndarray]
ValueFn = Callable[[RecordSignals, str, int, np.ndarray], np.ndarray]
CheckFn = Callable[[Sequence[RecordSignals]], "str | None"]
LabelFn = Callable[[str, int], tuple[str, ...]]


@dataclass(frozen=True, eq=False)
class Term:
    """One physical effect of the sensor model.

    ``columns(signals, sensor, axis)`` -> (N, k) per-sample regressors of output channel
    ``axis`` of ``sensor`` (in that channel's unit per unit parameter); the fit aggregates them
    like the measurements (block means, turn integrals). ``units``: one template per parameter,
    ``{u}`` = the channel's unit. ``needs``: what data would make the term identifiable;
    ``check``: returns why the records cannot determine it (or None). A term nonlinear in its
    parameters gives ``value(signals, sensor, axis, theta)`` -> (N,) instead, and ``initial``.
    """

    name: str
    doc: str
    sensors: tuple[str, ...]
    params: tuple[str, ...]
    units: tuple[str, ...]
    columns: ColumnFn | None = None
    needs: str = ""
    check: CheckFn | None = None
    labels: LabelFn | None = None
    value: ValueFn | None = None
    initial: tuple[float, ...] = ()
    #: largest plausible |parameter| per sensor (in the parameter's unit) and where that
    #: figure comes from; a fitted value beyond it is not a physical reading of the term
    plausible: Mapping[str, float] = field(default_factory=dict)
    plausible_source: str = ""
    #: one set of parameters for every channel the term acts on (a property of the bench, e.g.
    #: the plate's tilt, not of one output channel): the channels' columns share them
    shared: bool = False
    #: unknowns of ONE record (e.g. the plate's tilt seen by a static whose heading on the plate
    #: is not recorded): every record that ``owns`` selects gets its own parameters
    #: ``record_params`` (units ``record_units``), shared by the term's channels, named
    #: '{term}.{record}.{param}', with columns ``record_columns(signals, sensor, axis)`` ->
    #: (N, len(record_params)) (linear terms only); ``record_params_of(signals)`` names the
    #: subset one record carries when records differ (e.g. one heading where the rest is known)
    record_params: tuple[str, ...] = ()
    record_units: tuple[str, ...] = ()
    record_columns: ColumnFn | None = None
    owns: Callable[[RecordSignals], bool] | None = None
    record_params_of: Callable[[RecordSignals], tuple[str, ...]] | None = None
    #: the records' own unknowns belong to this sensor's channels alone ('': every sensor the
    #: term acts on), e.g. a pose's attitude to the accelerometer's misalignment
    record_sensor: str = ""
    #: the same parameters seen by another sensor (one geometry read by two sensors, e.g. a
    #: face's lean: gravity leaned on the accelerometer, the turn axis leaned on the gyro):
    #: ``twin_columns(signals, twin_sensor, axis)`` -> (N, len(params)) fill ``twin_sensor``'s
    #: rows of the same axis with the same parameters (linear per-channel terms only)
    twin_sensor: str = ""
    twin_columns: ColumnFn | None = None
    #: a built-in term's columns of the three channels at once, where one computation serves
    #: them all (a turn's lever-arm matrix, the plate's axes): ``columns_all(signals, sensor)``
    #: -> per axis exactly what ``columns(signals, sensor, axis)`` gives
    columns_all: Callable[[RecordSignals, str], Sequence[np.ndarray]] | None = None

    @property
    def physics(self) -> str:
        """The one-line physical explanation (first line of the docstring)."""
        return self.doc.strip().splitlines()[0] if self.doc.strip() else ""

    @property
    def nonlinear(self) -> bool:
        return self.value is not None

    def param_labels(self, sensor: str, axis: int) -> tuple[str, ...]:
        """Names of the parameters on channel ``axis`` of ``sensor`` (§2 names for base terms;
        a :attr:`shared` term's names do not depend on ``axis``)."""
        if self.labels is not None:
            return self.labels(sensor, axis)
        stem = f"{self.name}.{sensor}" + ("" if self.shared else f".{AXES[axis]}")
        return tuple(stem if len(self.params) == 1 else f"{stem}.{p}" for p in self.params)

    def param_units(self, sensor: str) -> tuple[str, ...]:
        """Units of the parameters for ``sensor``."""
        return tuple(u.replace("{u}", UNIT[sensor]) for u in self.units)

    def own_params(self, sig: RecordSignals) -> tuple[str, ...]:
        """The unknowns record ``sig`` carries of its own (of :attr:`record_params`)."""
        return self.record_params if self.record_params_of is None else self.record_params_of(sig)

    def owners(self, signals: Sequence[RecordSignals], sensor: str = "") -> list[int]:
        """Indices of the records in ``signals`` that carry unknowns of their own
        (:attr:`record_params`) on ``sensor``'s channels ('': any)."""
        if not self.record_params or self.owns is None:
            return []
        if self.record_sensor and sensor and sensor != self.record_sensor:
            return []
        return [i for i, s in enumerate(signals) if self.owns(s)]


@dataclass(frozen=True)
class Twin:
    """The same parameters seen by another sensor (:attr:`Term.twin_sensor`): ``columns``
    fill ``sensor``'s rows of the same axis (:attr:`Term.twin_columns`)."""

    sensor: str
    columns: ColumnFn


@dataclass(frozen=True)
class OwnUnknowns:
    """Unknowns of one record (:attr:`Term.record_params`): every record ``owns`` selects
    carries ``params`` (units ``units``) with columns ``columns``; ``params_of`` names the
    subset one record carries, ``sensor`` the sensor whose channels they belong to ('': every
    one the term acts on)."""

    params: tuple[str, ...]
    units: tuple[str, ...]
    columns: ColumnFn
    owns: Callable[[RecordSignals], bool]
    params_of: Callable[[RecordSignals], tuple[str, ...]] | None = None
    sensor: str = ""


def term(
    *,
    sensors: Sequence[str] = SENSORS,
    params: Mapping[str, str] | None = None,
    needs: str = "",
    check: CheckFn | None = None,
    labels: LabelFn | None = None,
    name: str | None = None,
    columns_all: Callable[[RecordSignals, str], Sequence[np.ndarray]] | None = None,
    twin: Twin | None = None,
    own: OwnUnknowns | None = None,
) -> Callable[[ColumnFn], Term]:
    """Decorator turning a column function into a :class:`Term` (see the README's example).

    ``params``: parameter name -> unit template (``{u}`` = the channel's unit); default one
    parameter in the channel's unit. The function's docstring is the term's physics.
    ``columns_all``, ``twin`` and ``own``: :attr:`Term.columns_all`, the term's
    :attr:`Term.twin_sensor` and its records' own unknowns (:attr:`Term.record_params`).
    """
    pmap = dict(params) if params is not None else {"c": "{u}"}

    def wrap(fn: ColumnFn) -> Term:
        doc = inspect.getdoc(fn) or ""
        if not doc:
            raise UserError(f"term {fn.__name__}: give it a docstring with the physics")
        bad = [s for s in sensors if s not in SENSORS]
        if bad or not pmap:
            raise UserError(f"term {fn.__name__}: sensors must be accel/gyro, params non-empty")
        made = Term(
            name=name or fn.__name__, doc=doc, sensors=tuple(sensors), params=tuple(pmap),
            units=tuple(pmap.values()), columns=fn, needs=needs, check=check, labels=labels,
            columns_all=columns_all,
        )  # fmt: skip
        if twin is not None:
            made = replace(made, twin_sensor=twin.sensor, twin_columns=twin.columns)
        if own is not None:
            made = replace(made, record_params=own.params, record_units=own.units,
                           record_columns=own.columns, owns=own.owns,
                           record_params_of=own.params_of, record_sensor=own.sensor)  # fmt: skip
        return made

    return wrap


def nonlinear_term(
    *,
    initial: Sequence[float],
    sensors: Sequence[str] = SENSORS,
    params: Mapping[str, str] | None = None,
    needs: str = "",
    check: CheckFn | None = None,
    name: str | None = None,
) -> Callable[[ValueFn], Term]:
    """Decorator for a term nonlinear in its parameters: the function gives the term's
    per-sample contribution ``value(signals, sensor, axis, theta)`` (N,); the fit linearises it
    around the current estimate (starting at ``initial``) and iterates."""
    pmap = dict(params) if params is not None else {"c": "{u}"}

    def wrap(fn: ValueFn) -> Term:
        doc = inspect.getdoc(fn) or ""
        if not doc:
            raise UserError(f"term {fn.__name__}: give it a docstring with the physics")
        if len(initial) != len(pmap):
            raise UserError(f"term {fn.__name__}: one initial value per parameter")
        return Term(
            name=name or fn.__name__, doc=doc, sensors=tuple(sensors), params=tuple(pmap),
            units=tuple(pmap.values()), value=fn, needs=needs, check=check,
            initial=tuple(float(x) for x in initial),
        )  # fmt: skip

    return wrap
