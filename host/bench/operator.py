"""The virtual operator: the person at a simulated bench who places and turns the cube.

:class:`CubeOperator` follows the calibration program's hints (``place``, ``turn``) by
scheduling the cube's motion on a running :class:`host.bench.sim.Simulator`, the way a person
would (hand turns with their own timing and wobble); ``sim://`` and ``emu://`` put one behind
their ports. It can misbehave on purpose (:data:`OPERATOR_FAULTS`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from host.bench.cube import hint_seed
from host.bench.physics import (
    Bench,
    Motion,
    move_to,
    static_motion,
    up_vector,
)
from host.bench.sim import Simulator, turn_motion
from host.session.records import turn_window_s

#: operator faults a virtual bench can play on purpose (``fault=NAME@K``: the K-th hint)
OPERATOR_FAULTS = ("wrong_face", "incomplete_turn", "too_fast")
#: peak rate of a ``too_fast`` turn, °/s (the gyro saturates at ±250 °/s)
TOO_FAST_PEAK_DPS = 320.0
#: fraction of the turns asked that an ``incomplete_turn`` makes
INCOMPLETE_FRACTION = 0.8
_NEXT_AXIS = {"x": "y", "y": "z", "z": "x"}


class CubeOperator:
    """The virtual operator of a simulated bench: follows the calibration program's hints by
    scheduling the cube's motion on a :class:`Simulator` (used by ``sim://`` and ``emu://``).

    ``place`` (``name="x_up"`` or ``up=[...]``): the cube rests with that face up from ``now``.
    ``turn`` (``axis``, ``direction`` ccw|cw, ``turns``, ``window_s``): from ``now`` (the start
    beep) the cube is ``axis`` up and turned by hand, starting 0.8–1.3 s later and stopping
    0.8–1.5 s before the window ends (:func:`turn_motion`). ``pose`` (``up``, ``first``): no
    cube, the hand moves the unit to a new attitude and holds it (:meth:`pose`). Other actions
    are ignored.
    ``faults`` maps :data:`OPERATOR_FAULTS` names to K: the K-th ``place`` puts the next axis
    up (``wrong_face``), the K-th ``turn`` stops at 0.8 of the turns (``incomplete_turn``) or
    peaks at 320 °/s (``too_fast``). ``rng`` draws the hand motions.
    ``cube`` (a board in a cube of several, :func:`host.bench.cube.hand_seed`): the hand of the
    cube's one operator; the n-th hint's motion is then drawn from it and n alone
    (:func:`host.bench.cube.hint_seed`, not from ``rng``), so every board of the cube given the
    same hints makes the same motion, each from its own ``now``. A hint's ``seq=N`` (any
    action) names n itself: a sitting that numbers its hints keeps a board that missed some
    (it dropped out and came back) in step with the others.
    """

    def __init__(
        self,
        rng: np.random.Generator,
        bench: Bench | None = None,
        faults: dict[str, float] | None = None,
        cube: np.random.SeedSequence | None = None,
    ) -> None:
        self.rng = rng
        self.bench = bench or Bench()
        self.faults = {k: v for k, v in (faults or {}).items() if k in OPERATOR_FAULTS}
        self.places = 0
        self.turns = 0
        self.cube = cube
        #: the hints received (every action, the ignored ones too)
        self.hints = 0

    def hint(self, sim: Simulator, now: float, action: str, **kw: Any) -> dict[str, Any]:
        """Act on one hint at simulated time ``now`` (s); -> what the operator did (dict:
        ``action``, ``done``, ``up``, ``fault``, ``start_s``...)."""
        self.hints += 1
        number = kw.pop("seq", self.hints)
        if not isinstance(number, int) or isinstance(number, bool) or number < 0:
            raise ValueError(f"seq={number!r}: a hint's number is a whole number, 0 or more")
        if self.cube is not None:
            self.rng = np.random.default_rng(hint_seed(self.cube, number))
        if action == "place":
            return self.place(sim, now, **kw)
        if action == "turn":
            return self.turn(sim, now, **kw)
        if action == "pose":
            return self.pose(sim, now, **kw)
        return {"action": action, "done": False}

    def pose(self, sim: Simulator, now: float, **kw: Any) -> dict[str, Any]:
        """Hold the unit (no cube) still with ``up`` (body vector) up: ``first`` puts it there
        at once; otherwise it rests where it was for 0.6–1.0 s after ``now`` (the beep), then
        the hand moves it there in 1.2–2.0 s (longer for more than 90°: under 150 °/s) by one
        rotation about a body axis (not the shortest: twisted by up to ±60° about the old up)
        and holds it still."""
        up = np.asarray(kw["up"], dtype=float)
        if kw.get("first"):
            sim.set_motion(static_motion(up), now)
            return {"action": "pose", "done": True, "up": up.tolist(), "start_s": now}
        attitude = sim.motion_at(now).kinematics(np.array([now]))[0][0]
        start = now + float(self.rng.uniform(0.6, 1.0))
        move = move_to(attitude, up, start, 1.0, float(self.rng.uniform(-60.0, 60.0)))
        # 1.2–2.0 s, longer for a larger angle: the peak rate 2·angle/duration under 150 °/s
        duration = max(float(self.rng.uniform(1.2, 2.0)), abs(move.angle_deg) / 75.0)
        move = dataclasses.replace(move, duration_s=duration)
        sim.set_motion(move, now)
        rest = tuple(tuple(row) for row in move.end_attitude.tolist())
        sim.set_motion(Motion(rest), start + duration)
        return {"action": "pose", "done": True, "up": up.tolist(), "start_s": start,
                "end_s": start + duration, "angle_deg": move.angle_deg}  # fmt: skip

    def place(self, sim: Simulator, now: float, **kw: Any) -> dict[str, Any]:
        """Put the cube at rest with a face (``name``) or a body vector (``up``) up."""
        self.places += 1
        fault = None
        if "up" in kw:
            up = np.asarray(kw["up"], dtype=float)
        else:
            name = str(kw.get("name", "z_up"))
            if self.faults.get("wrong_face") == self.places:
                axis, _, side = name.partition("_")
                name = f"{_NEXT_AXIS[axis]}_{side}"
                fault = "wrong_face"
            up = up_vector(name)
        sim.set_motion(static_motion(up), now)
        return {"action": "place", "done": True, "up": up.tolist(), "fault": fault, "start_s": now}

    def turn(self, sim: Simulator, now: float, **kw: Any) -> dict[str, Any]:
        """Turn the cube by hand about ``axis`` (up) within ``window_s`` from ``now``."""
        self.turns += 1
        axis = str(kw.get("axis", "z"))
        direction = str(kw.get("direction", "ccw")).lower()
        turns = int(kw.get("turns", 1))
        window = float(kw.get("window_s", turn_window_s(turns)))
        fault = None
        fraction, peak = 1.0, None
        if self.faults.get("incomplete_turn") == self.turns:
            fraction, fault = INCOMPLETE_FRACTION, "incomplete_turn"
        if self.faults.get("too_fast") == self.turns:
            peak, fault = TOO_FAST_PEAK_DPS, "too_fast"
        sign = 1 if direction == "ccw" else -1
        motion = turn_motion(
            self.rng, f"{axis}_up", now, window, turns, sign, self.bench.wobble_deg, fraction, peak
        )
        # after the turn the cube rests where it stopped (a whole turn: back at the ruler)
        sim.set_motion(motion, now)
        return {
            "action": "turn",
            "done": True,
            "up": up_vector(f"{axis}_up").tolist(),
            "fault": fault,
            "start_s": motion.profile.start,
            "end_s": motion.profile.end,
            "angle_deg": motion.profile.angle_deg,
        }
