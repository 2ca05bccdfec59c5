"""A virtual cube of several boards (host/bench/cube.py): each slot's place (lever arm,
mounting) drawn from the cube and the slot, a mounted sensor's output and constants, and the
hand shared by every board of one cube (issue 45 item 2)."""

from __future__ import annotations

import itertools
import urllib.parse

import numpy as np
import pytest

from host.bench.cube import (
    LEVER_ARM_M,
    MOUNTING_RAD,
    SLOTS,
    in_cube,
    simulate_sitting,
    slot_geometry,
)
from host.bench.operator import CubeOperator
from host.bench.options import OptionError, parse_sim_options
from host.bench.physics import Bench, Environment, static_motion
from host.bench.plan import Plan
from host.bench.sim import Simulator
from host.bench.truth import SensorTruth
from host.wire import sensor

ACC_LSB = sensor.G0 / 16384.0


def test_every_slot_has_its_own_lever_arm_on_every_axis_and_a_few_mrad_of_mounting() -> None:
    places = [slot_geometry(12, k) for k in range(SLOTS)]
    for k, p in enumerate(places):
        arm, tilt = np.abs(p.lever_arm_m), np.abs(p.mounting_rad)
        assert np.all((LEVER_ARM_M[0] <= arm) & (arm <= LEVER_ARM_M[1])), (k, arm)
        assert np.all((MOUNTING_RAD[0] <= tilt) & (tilt <= MOUNTING_RAD[1])), (k, tilt)
        # the slot's octant: bit i set, the sensor is on the negative side of axis i
        assert [v < 0 for v in p.lever_arm_m] == [bool(k >> i & 1) for i in range(3)]
    for a, b in itertools.combinations(places, 2):
        assert np.all(np.abs(np.subtract(a.lever_arm_m, b.lever_arm_m)) > 1e-4)
        assert np.all(np.abs(np.subtract(a.mounting_rad, b.mounting_rad)) > 1e-7)
    # a place is the cube's and the slot's: the same again, another in another cube
    assert slot_geometry(12, 3) == places[3]
    assert slot_geometry(13, 3) != places[3]
    with pytest.raises(ValueError, match="slot=8"):
        slot_geometry(12, 8)


def _rotation(theta: np.ndarray) -> np.ndarray:
    """Rot(θ) by the matrix exponential's series, apart from the code's Rodrigues formula."""
    k = np.array([[0, -theta[2], theta[1]], [theta[2], 0, -theta[0]], [-theta[1], theta[0], 0]])
    out, term = np.eye(3), np.eye(3)
    for n in range(1, 12):
        term = term @ k / n
        out = out + term
    return out


def test_a_mounted_ideal_sensor_reads_gravity_turned_by_its_mounting() -> None:
    """A perfect sensor at slot 5 of cube 2 on a level bench, each face up: it reads gravity
    along Rot(θ)ᵀ·up (to its quantisation), not along the cube's up."""
    truth = in_cube(SensorTruth.ideal(), 2, 5)
    rot = _rotation(np.array(truth.mounting_rad))
    bench = Bench(earth_rate=False, wobble_deg=0.0)
    for face in ("x_up", "y_dn", "z_up"):
        sim = Simulator(truth, bench, Environment(rise_c=0.0, room_amp_c=0.0), seed=1)
        sim.set_motion(static_motion(face), 0.0)
        mean = sim.run_until(2.0).accel.mean(axis=0)
        up = static_motion(face).pose_matrix[2]  # the body's up: third row of the attitude
        # no noise to dither it: each axis's mean is within half an LSB (6.0e-4 m/s²)
        assert np.max(np.abs(mean - bench.g * rot.T @ up)) < 0.55 * ACC_LSB, face
        # without the mounting the reading would be off by g·θ: a few hundredths of m/s²
        assert np.max(np.abs(mean - bench.g * up)) > 5e-3, face


def test_the_constants_of_a_mounted_sensor_are_its_own_turned_by_the_mounting() -> None:
    """The constants a calibration finds, referred to the cube's faces: M·Rot(θ)ᵀ. For a
    perfect sensor that is the small rotation itself: Axz = Ayz = θz, Axy = Azy = θy,
    Ayx = Azx = θx (method.md's names), scale errors of order θ²."""
    ideal = in_cube(SensorTruth.ideal(), 7, 1).constants()
    tx, ty, tz = slot_geometry(7, 1).mounting_rad
    for prefix in "AG":
        got = {k[1:]: ideal[prefix + k[1:]] for k in ("Axz", "Ayz", "Axy", "Azy", "Ayx", "Azx")}
        want = {"xz": tz, "yz": tz, "xy": ty, "zy": ty, "yx": tx, "zx": tx}
        for name, value in want.items():
            assert abs(got[name] - value) < 3e-5, (prefix, name, got[name], value)
        for axis in "xyz":
            assert abs(ideal[f"{prefix}{axis}{axis}"]) < 3e-5
    # a real unit: its misalignment and the mounting add (to first order); biases stay
    unit = SensorTruth.random(np.random.default_rng(4))
    mounted = in_cube(unit, 7, 1).constants()
    assert abs(mounted["Axz"] - (unit.Axz + tz)) < 1e-4
    assert abs(mounted["Gzx"] - (unit.Gzx + tx)) < 1e-4
    assert mounted["A0x"] == unit.A0x and mounted["G0z"] == unit.G0z
    assert SensorTruth.random(np.random.default_rng(4)).constants() == unit.constants()


def test_one_hand_makes_the_same_motion_on_every_board_from_its_own_now() -> None:
    """Two operators of one cube (the same hand seed), their boards at different device times
    and one of them having drawn from its own generator before: hint by hint the same faces,
    the same turn timings and wobble, shifted only by each board's ``now`` at the hint."""
    o = parse_sim_options({"cube": ["9"], "slot": ["2"], "seed": ["1"]}, "max", True)
    hand = o.draw().cube_ss
    assert hand is not None
    ops = [CubeOperator(np.random.default_rng(s), Bench(), cube=hand) for s in (1, 2)]
    ops[1].rng.uniform(size=5)
    sims = [Simulator(SensorTruth.ideal(), Bench(), seed=s) for s in (1, 2)]
    hints = [
        ("place", {"name": "y_dn"}),
        ("turn", {"axis": "y", "turns": 2, "window_s": 12}),
        ("pose", {"up": [0.0, 0.6, 0.8]}),
        ("turn", {"axis": "x", "direction": "cw"}),
    ]
    nows = [[3.0, 15.5, 30.0, 40.0], [3.013, 15.52, 30.004, 40.017]]
    taus = np.linspace(0.0, 11.9, 400)
    for h, (action, kw) in enumerate(hints):
        done = [
            op.hint(sim, now[h], action, **kw) for op, sim, now in zip(ops, sims, nows, strict=True)
        ]
        assert done[0]["done"] and done[1]["done"]
        for key in ("start_s", "end_s"):
            if key in done[0]:
                assert done[0][key] - nows[0][h] == pytest.approx(done[1][key] - nows[1][h])
        kin = [
            s.motion_at(now[h] + 1.0).kinematics(now[h] + taus)
            for s, now in zip(sims, nows, strict=True)
        ]
        assert np.max(np.abs(kin[0][0] - kin[1][0])) < 1e-9, action  # attitude
        assert np.max(np.abs(kin[0][1] - kin[1][1])) < 1e-9, action  # body rate, rad/s
    # another cube's hand turns otherwise
    other = CubeOperator(np.random.default_rng(1), Bench(), cube=parse_sim_options(
        {"cube": ["10"]}, "max", True).draw().cube_ss)  # fmt: skip
    sim = Simulator(SensorTruth.ideal(), Bench(), seed=1)
    other.hint(sim, 3.0, "place", name="y_dn")
    turned = other.hint(sim, 15.5, "turn", axis="y", turns=2, window_s=12)
    assert turned["start_s"] - 15.5 != pytest.approx(sims[0].motion_at(16.5).profile.start - 15.5)


def _query(**kw: str) -> dict[str, list[str]]:
    return urllib.parse.parse_qs(urllib.parse.urlencode(kw), keep_blank_values=True)


def test_cube_and_slot_options() -> None:
    o = parse_sim_options(_query(cube="0x2a", slot="7", seed="3"), "max", True)
    assert (o.cube, o.slot) == (42, 7)
    draw = o.draw()
    assert draw.truth.lever_arm_m == slot_geometry(42, 7).lever_arm_m
    assert draw.truth.mounting_rad == slot_geometry(42, 7).mounting_rad
    # the unit is still the seed's: its sensor errors are those of seed 3 alone
    alone = parse_sim_options(_query(seed="3"), "max", True).draw().truth
    assert draw.truth.Axx == alone.Axx and draw.truth.G0y == alone.G0y
    assert alone.mounting_rad == (0.0, 0.0, 0.0) and draw.cube_ss is not None
    assert parse_sim_options(_query(seed="3"), "max", True).draw().cube_ss is None
    # a cube without a slot: its slot 0; the cube's place whatever the unit's effects
    o = parse_sim_options(_query(cube="5", effects="bias"), "max", True)
    assert o.slot == 0 and o.draw().truth.lever_arm_m == slot_geometry(5, 0).lever_arm_m
    bad = (({"slot": "1"}, "slot"), ({"cube": "1", "slot": "8"}, "slot"), ({"cube": "-1"}, "cube"),
           ({"cube": "1.5"}, "cube"), ({"cube": "2", "slot": ""}, "slot"),
           ({"cube": str(2**32)}, "cube"))  # fmt: skip
    for query, key in bad:
        with pytest.raises(OptionError) as err:
            parse_sim_options(_query(**query), "max", True)
        assert err.value.key == key and "\n" not in str(err.value), query


def test_a_sitting_measures_every_record_on_every_board_with_one_hand() -> None:
    """simulate_sitting: two perfect units in cube 6 (each with its own room and clocks): every
    record on both; each turn's gyro integral, turned back by the board's mounting, is the same
    on both boards (one motion) — and differs between two cubes (another hand)."""
    plan = Plan(static_s=1.0, turns=1, statics=("z_up",), turn_axes=("z", "x"), warmup_s=0.0)
    units = [SensorTruth.ideal(), SensorTruth.ideal()]

    def turned(cube: int) -> list[dict[str, np.ndarray]]:
        out = []
        for k, records in enumerate(simulate_sitting(units, plan, cube, [3, 4])):
            rot = in_cube(units[k], cube, k).mounting
            out.append({n: rot @ _integral(r.t_ms, r.gyro) for n, r in records.items()})
        return out

    a, b = turned(6)
    assert set(a) == set(b) == {"z_up", "z_ccw", "z_cw", "x_ccw", "x_cw"}
    for name in ("z_ccw", "x_cw"):
        assert np.max(np.abs(a[name] - b[name])) < 0.05, name  # °: one hand
    other = turned(7)[0]
    assert np.max(np.abs(other["z_ccw"] - a["z_ccw"])) > 0.05  # another cube: another wobble
    with pytest.raises(ValueError, match="holds 8"):
        simulate_sitting([SensorTruth.ideal()] * 9, plan, 6, list(range(9)))


def _integral(t_ms: np.ndarray, rate: np.ndarray) -> np.ndarray:
    t = t_ms / 1000.0
    return np.sum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t)[:, None], axis=0)


def test_a_hint_numbered_by_the_sitting_keeps_a_board_that_missed_some_in_step() -> None:
    """A board that missed two hints (it was out) makes the same motion as the others once the
    sitting numbers its hints (``seq=``); counted by itself it would turn otherwise."""
    hand = parse_sim_options({"cube": ["3"]}, "max", True).draw().cube_ss
    ops = [CubeOperator(np.random.default_rng(0), Bench(), cube=hand) for _ in range(3)]
    sims = [Simulator(SensorTruth.ideal(), Bench(), seed=k) for k in range(3)]
    for n in (1, 2):  # boards 0 and 1 only; board 2 is out
        for op, sim in zip(ops[:2], sims[:2], strict=True):
            op.hint(sim, 5.0 * n, "place", seq=n, name="x_up")
    turn = {"axis": "y", "direction": "cw", "turns": 1, "window_s": 7.0}
    starts = [ops[k].hint(sims[k], 20.0, "turn", seq=3, **turn)["start_s"] for k in (0, 2)]
    assert starts[0] == starts[1]
    counted = CubeOperator(np.random.default_rng(0), Bench(), cube=hand)
    alone = counted.hint(Simulator(SensorTruth.ideal(), Bench()), 20.0, "turn", **turn)
    assert alone["start_s"] != starts[0]  # its own first hint: another draw
    with pytest.raises(ValueError, match="seq="):
        ops[0].hint(sims[0], 30.0, "place", seq=-1, name="z_up")
