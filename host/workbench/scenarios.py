"""Hidden-effect scenarios: a simulated session with ONE physical effect hidden in it, and what
the workbench makes of it (``python -m host demo hidden-effect``, the diagnosis tests, and
``benchmarks/model_bench.py``).

The sessions come from the virtual bench (:mod:`host.bench.sim`, imported when a case is made);
the diagnosis is :mod:`host.workbench.verdict`, the refit :mod:`host.workbench.ladder`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from host.errors import UserError
from host.model.dataset import Dataset, build_dataset, session_from_records
from host.model.noise import NoiseModel
from host.model.signals import AXES
from host.model.spec import parse_model
from host.workbench.ladder import Addition, add_term
from host.workbench.verdict import Diagnosis, diagnose

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
    records: Mapping[str, Any]
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


def hidden_effect_case(
    effect: str, seed: int = 0, *, tilted: bool = False, static_s: float = 10.0
) -> HiddenCase:
    """Simulate the session of demo ``effect`` (:data:`EFFECTS`) with ``seed``.

    The unit's §2 constants, noise and Gauss-Markov bias instability are drawn from the seed
    (:meth:`host.bench.truth.SensorTruth.random`); every other effect is off except the hidden
    one, on an axis chosen by the seed.
    """
    from host.bench.physics import Environment
    from host.bench.plan import Plan, simulate_session, tilted_45
    from host.bench.truth import SensorTruth

    if effect not in EFFECTS:
        raise UserError(f"unknown effect {effect!r}; known: {', '.join(EFFECTS)}")
    rng = np.random.default_rng([seed, 7919])
    base = SensorTruth.random(rng).only("linear", "noise", "bias_instability")
    axis = int(rng.integers(3))
    sign = 1.0 if rng.random() < 0.5 else -1.0
    vec = [0.0, 0.0, 0.0]
    env: Environment | None = None
    warmup_s = 600.0
    term, unit, truth = "", "", 0.0
    if effect == "temperature":
        truth = sign * float(rng.uniform(0.015, 0.03))
        vec[axis] = truth
        fields: dict[str, Any] = {"gyro_temp_bias": tuple(vec)}
        env = Environment(room_c=float(rng.uniform(20, 24)), rise_c=10.0, tau_s=250.0,
                          room_amp_c=2.5, room_period_s=240.0,
                          room_phase=float(rng.uniform(0, 2 * np.pi)))  # fmt: skip
        term, unit = f"temperature_bias:gyro:{AXES[axis]}", "°/s/°C"
    elif effect == "asymmetry":
        truth = sign * float(rng.uniform(0.004, 0.008))
        vec[axis] = truth
        fields = {"accel_scale_asym": tuple(vec)}
        term, unit = f"scale_asymmetry:accel:{AXES[axis]}", ""
    elif effect == "drift":
        truth = sign * float(rng.uniform(0.8, 1.5))
        vec[axis] = truth
        fields = {"gyro_drift": tuple(vec)}
        env = Environment(room_c=float(rng.uniform(20, 26)), rise_c=0.0, room_amp_c=0.0)
        term, unit = f"time_drift:gyro:{AXES[axis]}", "°/s/h"
        static_s = max(static_s, 30.0)  # the drift needs the statics spread over minutes
    elif effect == "warmup":
        truth = sign * float(rng.uniform(0.015, 0.03))
        vec[axis] = truth
        fields = {"gyro_temp_bias": tuple(vec)}
        env = Environment(room_c=float(rng.uniform(20, 24)), rise_c=40.0, tau_s=4000.0,
                          room_amp_c=0.0)  # fmt: skip
        warmup_s = 0.0
        static_s = max(static_s, 30.0)
        term, unit = f"temperature_bias:gyro:{AXES[axis]}", "°/s/°C"
    elif effect == "lever_arm":
        arm = rng.uniform(0.02, 0.05, 3) * np.where(rng.random(3) < 0.5, -1.0, 1.0)
        fields = {"lever_arm_m": tuple(float(v) for v in arm)}
        truth = float(arm[0])
        term, unit = "lever_arm:accel:xyz", "m"
    else:
        fields = {}
    truth_obj = dataclasses.replace(base, **fields)
    plan = Plan(static_s=static_s, gap_s=20.0, environment=env, warmup_s=warmup_s,
                tilted=tilted_45() if tilted else ())  # fmt: skip
    records = simulate_session(truth_obj, plan, seed)
    floor = {
        s: float(np.sqrt(np.mean(np.square(getattr(truth_obj, f"{s}_bias_instability")))))
        for s in ("accel", "gyro")
    }
    vector = tuple(float(v) for v in fields["lever_arm_m"]) if effect == "lever_arm" else ()
    return HiddenCase(effect, term, truth, unit, records, EFFECTS[effect], floor, vector)


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
