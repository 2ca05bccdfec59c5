"""The virtual cube that carries several boards: one operator's hand, each board at its place.

Boards given ``cube=C`` are in one cube held by one operator: :func:`hand_seed` (from C alone)
draws that operator's hand, hint by hint (:class:`host.bench.operator.CubeOperator`), so boards
given the same hints make the same motion. ``slot=K`` (0 … :data:`SLOTS` − 1) is the board's
place in the cube (:func:`slot_geometry`, from C and K): its sensor's offset from the cube's
centre (the lever arm, m, cube axes) and its mounting, a fixed rotation of a few mrad of the
board's axes against the cube's. :func:`in_cube` makes them part of a unit's
:class:`~host.bench.truth.SensorTruth`, so a board's calibration, which refers every axis to
the cube's faces, finds its own misalignment and lever arm. The unit itself (its sensor's
errors) comes from its own seed, as on a bench of one board. :func:`simulate_sitting` measures
a plan of records on several boards of one cube at once (the fast path of
:func:`host.bench.plan.simulate_session`, for tests and benchmarks).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from host.bench.plan import Plan, simulate_session
from host.bench.truth import SensorTruth, Vec3
from host.session.records import Record

#: places in one cube: one per octant of its centre
SLOTS = 8
#: a slot's lever arm, per axis: |r_i| within this range (m), its sign the slot's octant
LEVER_ARM_M = (0.015, 0.04)
#: a slot's mounting, per axis: |θ_i| within this range (rad; a rotation vector)
MOUNTING_RAD = (0.001, 0.005)
#: the first word of every cube seed: keeps the cube's draws apart from a unit seed's
_TAG = 0x6375_6265  # "cube"


@dataclass(frozen=True)
class SlotGeometry:
    """A board's place in the cube: ``lever_arm_m`` its sensor's offset from the cube's centre
    (cube axes, m), ``mounting_rad`` the rotation vector (rad) that turns the cube's axes into
    the board's (v_cube = Rot(θ) · v_board)."""

    lever_arm_m: Vec3
    mounting_rad: Vec3


def hand_seed(cube: int) -> np.random.SeedSequence:
    """The seed of the hand of cube ``cube``'s operator (the same for every board in it)."""
    return np.random.SeedSequence([_TAG, cube, 0])


def hint_seed(hand: np.random.SeedSequence, number: int) -> np.random.SeedSequence:
    """The seed of the ``number``-th hint's motion (1, 2, …) by the hand ``hand``: the same
    hint number draws the same motion on every board, whatever each drew before."""
    return np.random.SeedSequence(hand.entropy, spawn_key=(*hand.spawn_key, number))


def slot_geometry(cube: int, slot: int) -> SlotGeometry:
    """Slot ``slot``'s lever arm and mounting in cube ``cube`` (module docstring): the lever
    arm's signs are the slot's octant (bit i of ``slot`` set: negative along axis i), its
    sizes and the mounting's drawn from ``cube`` and ``slot``."""
    if not 0 <= slot < SLOTS:
        raise ValueError(f"slot={slot} is outside 0 … {SLOTS - 1}")
    rng = np.random.default_rng(np.random.SeedSequence([_TAG, cube, 1, slot]))
    octant = np.array([-1.0 if slot >> i & 1 else 1.0 for i in range(3)])
    arm = octant * rng.uniform(*LEVER_ARM_M, 3)
    tilt = rng.choice([-1.0, 1.0], 3) * rng.uniform(*MOUNTING_RAD, 3)
    return SlotGeometry(_vec3(arm), _vec3(tilt))


def in_cube(truth: SensorTruth, cube: int, slot: int) -> SensorTruth:
    """``truth`` of a unit mounted at ``slot`` of cube ``cube``: its lever arm is the slot's
    (the unit's own offset on a bench of one board is replaced: the sensor is where the slot
    puts it) and its mounting the slot's."""
    place = slot_geometry(cube, slot)
    return dataclasses.replace(
        truth, lever_arm_m=place.lever_arm_m, mounting_rad=place.mounting_rad
    )


def simulate_sitting(
    units: Sequence[SensorTruth], plan: Plan, cube: int, seeds: Sequence[int]
) -> list[dict[str, Record]]:
    """One sitting: every record of ``plan`` measured on the boards ``units`` mounted in slots
    0, 1, … of cube ``cube``, with one hand (every board turned by the same motions), each board
    with its own place (:func:`in_cube`) and its own room, clock and noise (``seeds``); -> each
    board's records, in slot order."""
    if len(units) > SLOTS:
        raise ValueError(f"a cube holds {SLOTS} boards, not {len(units)}")
    return [
        simulate_session(in_cube(truth, cube, k), plan, seed, hand=hand_seed(cube))
        for k, (truth, seed) in enumerate(zip(units, seeds, strict=True))
    ]


def _vec3(a: np.ndarray) -> Vec3:
    return (float(a[0]), float(a[1]), float(a[2]))
