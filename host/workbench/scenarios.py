"""Hidden-effect scenarios: a simulated session with ONE physical effect hidden in it, and what
the workbench makes of it (``python3 -m host demo hidden-effect``, the diagnosis tests, and
``benchmarks/model_bench.py``).

The sessions come from the virtual bench (:mod:`host.bench.sim`, imported when a case is made);
the diagnosis is :mod:`host.workbench.verdict`, the refit :mod:`host.workbench.ladder`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from host.errors import UserError
from host.model.dataset import Dataset, build_dataset, session_from_records
from host.model.noise import NoiseModel
from host.model.signals import AXES
from host.model.spec import parse_model
from host.session.records import Record
from host.workbench.ladder import Addition, add_term
from host.workbench.verdict import Diagnosis, diagnose

if TYPE_CHECKING:  # the virtual bench is imported when a case is made
    from host.bench.physics import Environment
    from host.bench.truth import SensorTruth, Vec3

# ---- hidden-effect scenarios ----------------------------------------------------------------
#: effect name -> one-line description
EFFECTS: dict[str, str] = {
    "temperature": "gyro bias linear in chip temperature; the room's air conditioning cycles "
    "(±2.5 °C, 4 min), so the temperature goes up AND down during the session",
    "asymmetry": "accelerometer scale asymmetry (scale(+g) ≠ scale(−g)); six ±1 g attitudes "
    "(add --tilted for the 12 45° attitudes that separate it from nonlinearity)",
    "drift": "gyro bias drifting linearly with time since power-on, at constant temperature",
    "warmup": "gyro bias linear in temperature while the chip warms steadily (~0.5 °C/min): "
    "temperature and time cannot be told apart (confounded)",
    "lever_arm": "the sensor sits 2–5 cm off the cube's centre on every axis: while the cube "
    "turns the accelerometer reads the centripetal ω×(ω×r) and tangential ω̇×r accelerations",
    "none": "control: nothing hidden (the §2 linear model, white noise, bias instability)",
}
#: the demo runs these by default (``--effect all``)
DEFAULT_EFFECTS = ("temperature", "asymmetry", "drift", "none")


@dataclass(frozen=True, eq=False)
class HiddenCase:
    """A simulated session with one hidden effect: ``term`` (``name:sensor:axis``, "" for the
    control) with true coefficient ``truth`` (in the term's unit), the records and the plan."""

    effect: str
    term: str
    truth: float
    unit: str
    records: Mapping[str, Record]
    description: str
    #: the unit's bias wander per sensor, m/s² and °/s: the RMS over the axes of its
    #: Gauss-Markov bias instability (steady-state std) — what a noise file of this unit
    #: gives the workbench (``--noise``), where the session's own repeated attitudes (the
    #: default floor) also carry any slow effect that differs between them
    known_floor: Mapping[str, float] = dataclasses.field(default_factory=dict)
    #: every component of a vector effect's truth (the lever arm's x, y, z in m), else ()
    truth_vector: tuple[float, ...] = ()

    def known_noise(self) -> NoiseModel:
        """The noise model with :attr:`known_floor` (as ``--noise``/``--floor`` would give)."""
        return NoiseModel(floor=dict(self.known_floor))


@dataclass(frozen=True, eq=False)
class _Hidden:
    """What one effect changes in a simulated session: the unit (``put``: the effect put into
    a :class:`host.bench.truth.SensorTruth`) and the room (``environment``, None: the plan's),
    the term that would fit it with its true coefficient and unit, the warm-up before the first
    record (s) and the shortest static record it needs (s; None: any)."""

    put: Callable[[SensorTruth], SensorTruth]
    term: str = ""
    unit: str = ""
    truth: float = 0.0
    environment: Environment | None = None
    warmup_s: float = 600.0
    static_min_s: float | None = None
    #: every component of a vector effect's truth (the lever arm's x, y, z in m), else ()
    vector: tuple[float, ...] = ()


def hidden_effect_case(
    effect: str, seed: int = 0, *, tilted: bool = False, static_s: float = 10.0
) -> HiddenCase:
    """Simulate the session of demo ``effect`` (:data:`EFFECTS`) with ``seed``.

    The unit's §2 constants, noise and Gauss-Markov bias instability are drawn from the seed
    (:meth:`host.bench.truth.SensorTruth.random`); every other effect is off except the hidden
    one, on an axis chosen by the seed.
    """
    from host.bench.plan import Plan, simulate_session, tilted_45
    from host.bench.truth import SensorTruth

    if effect not in EFFECTS:
        raise UserError(f"unknown effect {effect!r}; known: {', '.join(EFFECTS)}")
    rng = np.random.default_rng([seed, 7919])
    base = SensorTruth.random(rng).only("linear", "noise", "bias_instability")
    axis = int(rng.integers(3))
    sign = 1.0 if rng.random() < 0.5 else -1.0
    hidden = _HIDDEN[effect](rng, axis, sign)
    if hidden.static_min_s is not None:
        static_s = max(static_s, hidden.static_min_s)
    truth = hidden.put(base)
    plan = Plan(static_s=static_s, gap_s=20.0, environment=hidden.environment,
                warmup_s=hidden.warmup_s, tilted=tilted_45() if tilted else ())  # fmt: skip
    records = simulate_session(truth, plan, seed)
    return HiddenCase(effect, hidden.term, hidden.truth, hidden.unit, records, EFFECTS[effect],
                      _known_floor(truth), hidden.vector)  # fmt: skip


def _known_floor(truth: SensorTruth) -> dict[str, float]:
    """Per sensor the RMS over the axes of the unit's bias instability (m/s², °/s)."""
    return {
        s: float(np.sqrt(np.mean(np.square(getattr(truth, f"{s}_bias_instability")))))
        for s in ("accel", "gyro")
    }


def _on_axis(axis: int, value: float) -> Vec3:
    """(x, y, z) with ``value`` on ``axis`` and 0 on the others."""
    vec = [0.0, 0.0, 0.0]
    vec[axis] = value
    return vec[0], vec[1], vec[2]


def _temperature(rng: np.random.Generator, axis: int, sign: float) -> _Hidden:
    """Gyro bias linear in temperature, the room's air conditioning cycling the chip."""
    from host.bench.physics import Environment

    truth = sign * float(rng.uniform(0.015, 0.03))
    env = Environment(room_c=float(rng.uniform(20, 24)), rise_c=10.0, tau_s=250.0,
                      room_amp_c=2.5, room_period_s=240.0,
                      room_phase=float(rng.uniform(0, 2 * np.pi)))  # fmt: skip
    vec = _on_axis(axis, truth)
    return _Hidden(lambda t: dataclasses.replace(t, gyro_temp_bias=vec),
                   f"temperature_bias:gyro:{AXES[axis]}", "°/s/°C", truth, env)  # fmt: skip


def _asymmetry(rng: np.random.Generator, axis: int, sign: float) -> _Hidden:
    """Accelerometer scale asymmetry on one axis."""
    truth = sign * float(rng.uniform(0.004, 0.008))
    vec = _on_axis(axis, truth)
    return _Hidden(lambda t: dataclasses.replace(t, accel_scale_asym=vec),
                   f"scale_asymmetry:accel:{AXES[axis]}", "", truth)  # fmt: skip


def _drift(rng: np.random.Generator, axis: int, sign: float) -> _Hidden:
    """Gyro bias drifting with time at a constant temperature; the statics spread over
    minutes (30 s each at least)."""
    from host.bench.physics import Environment

    truth = sign * float(rng.uniform(0.8, 1.5))
    env = Environment(room_c=float(rng.uniform(20, 26)), rise_c=0.0, room_amp_c=0.0)
    vec = _on_axis(axis, truth)
    return _Hidden(lambda t: dataclasses.replace(t, gyro_drift=vec),
                   f"time_drift:gyro:{AXES[axis]}", "°/s/h", truth, env,
                   static_min_s=30.0)  # fmt: skip


def _warmup(rng: np.random.Generator, axis: int, sign: float) -> _Hidden:
    """Gyro bias linear in temperature while the chip warms steadily from power-on (no
    warm-up before the first record; statics of 30 s at least)."""
    from host.bench.physics import Environment

    truth = sign * float(rng.uniform(0.015, 0.03))
    env = Environment(room_c=float(rng.uniform(20, 24)), rise_c=40.0, tau_s=4000.0,
                      room_amp_c=0.0)  # fmt: skip
    vec = _on_axis(axis, truth)
    return _Hidden(lambda t: dataclasses.replace(t, gyro_temp_bias=vec),
                   f"temperature_bias:gyro:{AXES[axis]}", "°/s/°C", truth, env,
                   warmup_s=0.0, static_min_s=30.0)  # fmt: skip


def _lever_arm(rng: np.random.Generator, axis: int, sign: float) -> _Hidden:
    """The sensor 2–5 cm off the cube's centre on every axis (each sign drawn)."""
    arm = rng.uniform(0.02, 0.05, 3) * np.where(rng.random(3) < 0.5, -1.0, 1.0)
    vector = (float(arm[0]), float(arm[1]), float(arm[2]))
    return _Hidden(lambda t: dataclasses.replace(t, lever_arm_m=vector),
                   "lever_arm:accel:xyz", "m", float(arm[0]), vector=vector)  # fmt: skip


def _none(rng: np.random.Generator, axis: int, sign: float) -> _Hidden:
    """The control: nothing hidden."""
    return _Hidden(dataclasses.replace)


#: effect -> what it changes in the simulation, from the seed's generator, axis and sign
_HIDDEN: dict[str, Callable[[np.random.Generator, int, float], _Hidden]] = {
    "temperature": _temperature,
    "asymmetry": _asymmetry,
    "drift": _drift,
    "warmup": _warmup,
    "lever_arm": _lever_arm,
    "none": _none,
}


def case_dataset(case: HiddenCase, noise: NoiseModel | None = None) -> Dataset:
    """The :class:`~host.model.dataset.Dataset` of a hidden-effect case (no files written)."""
    return build_dataset(session_from_records(case.records), noise=noise)


# ---- what the workbench finds ----------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class DemoOutcome:
    """What the workbench made of one hidden-effect case."""

    case: HiddenCase
    diagnosis: Diagnosis
    addition: Addition | None

    @property
    def found(self) -> str:
        return self.diagnosis.significant[0].label if self.diagnosis.significant else ""

    @property
    def group(self) -> tuple[str, ...]:
        if not self.diagnosis.significant:
            return ()
        c = self.diagnosis.significant[0]
        return (c.label, *c.confounded_with)

    @property
    def coefficient(self) -> float:
        if self.addition is None or not self.case.term:
            return math.nan
        name = parse_model(self.case.term)[0]
        labels = name.term.param_labels(name.sensor, name.axes[0])
        for p in self.addition.after.parameters:
            if p.name == labels[0]:
                return p.value
        return math.nan

    @property
    def named_hidden(self) -> bool:
        """The hidden term is the first one named, or in its confounded group."""
        return self.case.term in self.group

    @property
    def coefficient_error(self) -> float:
        """|fitted − truth| / |truth| of the hidden term's coefficient (1; NaN for the control)."""
        t = self.case.truth
        return abs(self.coefficient - t) / abs(t) if t else math.nan


def run_case(case: HiddenCase, noise: NoiseModel | None = None) -> DemoOutcome:
    """Diagnose the base model on the case's records and add the hidden term (or, for the
    control, the top candidate if any)."""
    ds = case_dataset(case, noise)
    model = parse_model("base")
    d = diagnose(ds, model)
    add = case.term or (d.significant[0].label if d.significant else "")
    a = add_term(ds, model, add) if add else None
    return DemoOutcome(case, d, a)
