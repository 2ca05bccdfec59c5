"""The model spec grammar: ``"base,temperature_bias:gyro:x"`` <-> the model terms
(:class:`ModelTerm`: a term on some channels of one sensor)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from host.errors import UserError
from host.model.catalogue import BASE, CATALOGUE
from host.model.signals import AXES, SENSORS, UNIT, RecordSignals
from host.model.terms import Term


# ---- model specification --------------------------------------------------------------------
@dataclass(frozen=True)
class ModelTerm:
    """A term applied to some channels: ``term`` on ``sensor`` axes ``axes`` (indices)."""

    term: Term
    sensor: str
    axes: tuple[int, ...]

    @property
    def label(self) -> str:
        """'temperature_bias:gyro:x' style."""
        return f"{self.term.name}:{self.sensor}:{''.join(AXES[a] for a in self.axes)}"

    @property
    def n_params(self) -> int:
        return len(self.term.params) * (1 if self.term.shared else len(self.axes))

    def count(self, signals: Sequence[RecordSignals]) -> int:
        """Parameters on the records ``signals``: :attr:`n_params` and the unknowns of the
        records that carry their own (:attr:`Term.record_params`)."""
        t = self.term
        owners = t.owners(signals, self.sensor)
        return self.n_params + sum(len(t.own_params(signals[i])) for i in owners)

    def slots(self, signals: Sequence[RecordSignals] = ()) -> list[tuple[int | None, str, str]]:
        """(output axis or None for a shared parameter, name, parameter key) of each of its
        parameters, in the order of its design columns; with ``signals``, the unknowns of the
        records that carry their own follow (key '{record}.{param}')."""
        t = self.term
        if t.shared:
            names = t.param_labels(self.sensor, self.axes[0])
            out: list[tuple[int | None, str, str]] = [
                (None, n, k) for n, k in zip(names, t.params, strict=True)
            ]
        else:
            out = [
                (ax, n, t.params[q])
                for ax in self.axes
                for q, n in enumerate(t.param_labels(self.sensor, ax))
            ]
        for i in t.owners(signals, self.sensor):
            rec = signals[i].name
            out.extend(
                (None, f"{t.name}.{rec}.{p}", f"{rec}.{p}") for p in t.own_params(signals[i])
            )
        return out

    def unit(self, key: str) -> str:
        """The unit of the parameter with key ``key`` (a :meth:`slots` key)."""
        t = self.term
        if key in t.params:
            return t.param_units(self.sensor)[t.params.index(key)]
        p = key.rsplit(".", 1)[-1]
        return t.record_units[t.record_params.index(p)].replace("{u}", UNIT[self.sensor])


def parse_model(spec: str, catalogue: Mapping[str, Term] | None = None) -> list[ModelTerm]:
    """``"base,temperature_bias:gyro:x"`` -> model terms. Items ``term[:sensor[:axes]]``;
    ``base`` = bias, scale, misalignment, g_sensitivity. UserError on a bad spec."""
    cat = catalogue if catalogue is not None else CATALOGUE
    items = [s.strip() for s in spec.split(",") if s.strip()]
    if not items:
        raise UserError("empty model spec; e.g. --model base or --model bias,scale")
    out: list[ModelTerm] = []
    for item in items:
        parts = item.split(":")
        if len(parts) > 3:
            raise UserError(f"model item {item!r}: expected term[:sensor[:axes]]")
        name = parts[0]
        is_base = name == "base"
        if not is_base and name not in cat:
            raise UserError(f"unknown term {name!r}; known: base, {', '.join(cat)}")
        for t in [cat[n] for n in BASE] if is_base else [cat[name]]:
            sensors = t.sensors
            if len(parts) > 1 and parts[1]:
                if parts[1] not in SENSORS:
                    raise UserError(f"model item {item!r}: sensor must be accel or gyro")
                if parts[1] not in t.sensors:
                    if is_base:
                        continue  # base:accel -> g_sensitivity has no accel part
                    raise UserError(f"term {name} does not act on the {parts[1]}")
                sensors = (parts[1],)
            axes_txt = parts[2] if len(parts) > 2 and parts[2] else AXES
            if any(c not in AXES for c in axes_txt):
                raise UserError(f"model item {item!r}: axes must be letters of xyz")
            axes = tuple(sorted({AXES.index(c) for c in axes_txt}))
            out.extend(ModelTerm(t, s, axes) for s in sensors)
    return merge_model(out)


def merge_model(terms: Iterable[ModelTerm]) -> list[ModelTerm]:
    """Join the axes of repeated (term, sensor) pairs, keeping first-seen order."""
    order: list[tuple[str, str]] = []
    axes: dict[tuple[str, str], set[int]] = {}
    objs: dict[tuple[str, str], Term] = {}
    for mt in terms:
        key = (mt.term.name, mt.sensor)
        if key not in axes:
            order.append(key)
            axes[key] = set()
            objs[key] = mt.term
        axes[key].update(mt.axes)
    return [ModelTerm(objs[k], k[1], tuple(sorted(axes[k]))) for k in order]


def model_spec(model: Sequence[ModelTerm]) -> str:
    """The spec string of a model (inverse of :func:`parse_model`)."""
    return ",".join(mt.label for mt in model)


def short_spec(model: Sequence[ModelTerm]) -> str:
    """The spec with ``base`` for the whole §2 linear model and ``term:sensor`` for all
    three axes: 'base,temperature_bias:gyro:y' (same model as :func:`model_spec`)."""
    full = {(mt.term.name, mt.sensor): mt.axes for mt in model}
    base = [ModelTerm(CATALOGUE[n], s, (0, 1, 2)) for n in BASE for s in CATALOGUE[n].sensors]
    has_base = all(full.get((b.term.name, b.sensor)) == (0, 1, 2) for b in base)
    items = ["base"] if has_base else []
    for mt in model:
        if has_base and mt.term.name in BASE:
            continue
        axes = "" if mt.axes == (0, 1, 2) else ":" + "".join(AXES[a] for a in mt.axes)
        items.append(f"{mt.term.name}:{mt.sensor}{axes}")
    return ",".join(items)
