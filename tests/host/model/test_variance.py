"""The named variance components of the turns (host.model.variance): measured from the closure
of the turns made both ways, with their own degrees of freedom, never a constant."""

from __future__ import annotations

import math

import numpy as np
import pytest

from host.model.variance import TurnClosure, turn_angle_sigma, turn_wobble_sigma


def _closures(rng: np.random.Generator, k: int, sigma: float, white: float) -> list[TurnClosure]:
    """k axes turned both ways (720° each), rest reading 0.5 °/s over 12 s turns: the hand's
    angle error of std ``sigma`` per turn and white noise of variance ``white`` on the sum."""
    out = []
    for i in range(k):
        e1, e2 = rng.normal(0.0, sigma, 2)
        noise = rng.normal(0.0, math.sqrt(white))
        rest = 0.5
        out.append(
            TurnClosure(
                i % 3, i % 3, (720.0 + e1 + rest * 12 + noise, -720.0 + e2 + rest * 12), rest,
                (12.0, 12.0), white,
            )
        )  # fmt: skip
    return out


def test_turn_angle_comes_back_from_the_closures_and_is_zero_for_exact_turns() -> None:
    rng = np.random.default_rng(1)
    got = turn_angle_sigma(_closures(rng, 3000, 0.4, 1e-4))
    assert got.value == pytest.approx(0.4, rel=0.05) and got.dof == 3000
    assert got.sigma < 0.02 and not got.plausible
    exact = turn_angle_sigma(_closures(rng, 3, 0.0, 1e-4))
    assert exact.value == 0.0  # unresolved: not a floor that widens the yardstick
    assert "not measured" in turn_angle_sigma([]).describe()


def test_a_turn_missed_by_a_whole_step_is_implausible() -> None:
    rng = np.random.default_rng(2)
    big = turn_angle_sigma(_closures(rng, 3, 10.0, 1e-4))
    assert big.plausible and "IMPLAUSIBLE" in big.describe()
    assert "asymmetry" in big.absorbs  # what else the closure could be, said in words
    wob = turn_wobble_sigma(_closures(rng, 6, 2.0, 1e-4))
    assert wob.name == "turn wobble" and wob.plausible
