"""Poses without a cube (host/model/poses.py): the first estimate of the accelerometer and
of each pose's attitude, the attitude's correction, the frame's convention in the fit."""

from __future__ import annotations

import numpy as np
import pytest

from host.calib.calibration import CalibrationOptions, calibrate_from_records
from host.model.poses import (
    FRAME_FIXED,
    MoveInput,
    attitude_basis,
    attitudes,
    move_geometry,
    move_rows,
    preliminary_accel,
    preliminary_gyro,
    propagate,
    rotation_steps,
)
from host.session.directory import Session
from host.session.records import Record, pose_name

G = 9.80665


def _units(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _unit_matrix(rng: np.random.Generator) -> np.ndarray:
    m = np.eye(3) + np.diag(rng.uniform(-0.02, 0.02, 3))
    m[0, 1], m[0, 2], m[1, 2] = rng.uniform(-0.01, 0.01, 3)
    return m


def test_preliminary_accel_recovers_an_upper_triangular_unit() -> None:
    rng = np.random.default_rng(7)
    m, b = _unit_matrix(rng), rng.uniform(-0.5, 0.5, 3)
    ups = _units(rng, 20)
    means = (G * ups) @ m.T + b
    got_m, got_b = preliminary_accel(means, G)
    assert np.allclose(got_m, m, atol=1e-9) and np.allclose(got_b, b, atol=1e-8)
    assert np.allclose(attitudes(means, got_m, got_b), ups, atol=1e-9)


def test_preliminary_accel_refuses_what_it_cannot_determine() -> None:
    rng = np.random.default_rng(2)
    with pytest.raises(ValueError, match="at least 9 poses"):
        preliminary_accel(G * _units(rng, 8), G)
    # every pose about one axis: the scale along it is not seen
    flat = np.column_stack([np.cos(np.arange(12.0)), np.sin(np.arange(12.0)), np.zeros(12)])
    with pytest.raises(ValueError, match="too alike"):
        preliminary_accel(G * flat, G)


def test_attitude_basis_is_across_up() -> None:
    rng = np.random.default_rng(3)
    for up in [*_units(rng, 20), np.array([0.0, 0.0, 1.0]), np.array([-1.0, 0.0, 0.0])]:
        e = attitude_basis(up)
        assert np.allclose(e @ e.T, np.eye(2), atol=1e-12)
        assert np.allclose(e @ up, 0.0, atol=1e-12)
        assert np.allclose(np.cross(up, e[0]), e[1])


def _pose_session(rng: np.random.Generator, m: np.ndarray, b: np.ndarray, n: int) -> Session:
    records = {}
    for i, up in enumerate(_units(rng, n), start=1):
        k = 200
        accel = (G * up) @ m.T + b + rng.normal(0, 0.02, (k, 3))
        gyro = rng.normal(0, 0.05, (k, 3)) + [0.4, -0.2, 0.1]
        meta = {"power_on_s": f"{10.0 * i:.1f}"}
        records[pose_name(i)] = Record(pose_name(i), np.arange(k) * 10.0, accel, gyro,
                                       np.full(k, 30.0), meta)  # fmt: skip
    return Session(serial="P", records=records)


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_pose_session_is_calibrated_in_the_accelerometers_frame() -> None:
    rng = np.random.default_rng(11)
    m, b = _unit_matrix(rng), rng.uniform(-0.3, 0.3, 3)
    res = calibrate_from_records(
        _pose_session(rng, m, b, 24), CalibrationOptions(latitude_deg=45.0, height_m=0.0)
    )
    by = {p.name: p for p in res.parameters}
    assert res.g == pytest.approx(G, abs=2e-3)
    # the truth is upper triangular: it is in the convention's frame already
    want = {"Axx": m[0, 0] - 1, "Ayy": m[1, 1] - 1, "Azz": m[2, 2] - 1, "Axz": m[0, 1],
            "Axy": -m[0, 2], "Ayx": m[1, 2], "A0x": b[0], "A0y": b[1], "A0z": b[2]}  # fmt: skip
    for name, value in want.items():
        p = by[name]
        # the simulated g is 9.80665, the fit's local g differs by δg: scales move by δg/g
        slack = abs(res.g - G) / G if name[1] == name[2] else 0.0
        assert abs(p.value - value) < 4 * p.stderr + slack, (name, p.value, value, p.stderr)
    for name in FRAME_FIXED:
        assert (by[name].value, by[name].stderr) == (0.0, 0.0)
    # every pose carries its attitude; the gyro's scales need rotations the rests lack
    assert np.isfinite(by["misalignment.pose_01.attitude_a"].value)
    assert not np.isfinite(by["Gxx"].value)
    note = next(n for n in res.notes if n.startswith("frame:"))
    assert "Ayz, Azy, Azx = 0" in note and "Axz − Ayz" in note
    assert res.fit.untestable == ()


def _wobbly_rate(n: int) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(n) * 0.01
    rate = np.column_stack([50 * np.sin(2 * t), 80 * np.cos(t), 30 + 20 * t])
    return t, rate


def test_a_constant_rate_turns_gravity_exactly() -> None:
    # 90 °/s about z for 2 s in 6 steps: a half turn, whatever the step
    t = np.linspace(0.0, 2.0, 7)
    rot = propagate(rotation_steps(t, np.tile([0.0, 0.0, 90.0], (7, 1))))[-1]
    assert np.allclose(rot @ [1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], atol=1e-12)
    # a room-fixed vector seen in the body turns the other way: +90° about z takes x to -y
    rot = propagate(rotation_steps(t[:2], np.tile([0.0, 0.0, 270.0], (2, 1))))[-1]
    assert np.allclose(rot @ [1.0, 0.0, 0.0], [0.0, -1.0, 0.0], atol=1e-12)


def test_move_weights_are_the_kinematics_linearised() -> None:
    t, rate = _wobbly_rate(300)
    up = np.array([0.3, 0.4, 0.866]) / np.linalg.norm([0.3, 0.4, 0.866])
    across = attitude_basis(np.array([0.1, 0.9, 0.2]))
    miss, w, _ = move_geometry(t, rate, up, across)
    change = np.random.default_rng(1).normal(0, 0.5, rate.shape)
    h = 1e-4
    moved, _, _ = move_geometry(t, rate + h * change, up, across)
    numeric = np.degrees(moved - miss) / h
    assert np.allclose(np.einsum("knj,nj->k", w, change), numeric, rtol=2e-3, atol=1e-6)


def test_preliminary_gyro_recovers_the_gyro_from_moves() -> None:
    rng = np.random.default_rng(4)
    m = np.eye(3) + rng.normal(0, 0.01, (3, 3))
    moves = []
    for _ in range(8):
        t, rate = _wobbly_rate(200)
        rate = rate @ _rotation(rng).T  # a different path each time
        up = _units(rng, 1)[0]
        end = propagate(rotation_steps(t, rate))[-1] @ up
        moves.append(MoveInput(t, rate @ m.T, up, attitude_basis(end)))
    assert np.allclose(preliminary_gyro(moves), m, atol=1e-9)
    with pytest.raises(ValueError, match="at least 5"):
        preliminary_gyro(moves[:4])


def _rotation(rng: np.random.Generator) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def test_move_rows_are_uncorrelated_and_read_both_attitudes() -> None:
    t, rate = _wobbly_rate(250)
    up = np.array([0.0, 0.6, 0.8])
    end = propagate(rotation_steps(t, rate))[-1] @ up
    white = np.array([1e-4, 3e-4, 2e-4])
    rows = move_rows(t, rate, rate, up, end, white)
    cov = np.einsum("kan,lan,a->kl", rows.weights, rows.weights, white)
    assert np.allclose(cov, np.diag(rows.sigma**2), rtol=1e-9, atol=1e-15)
    # the reference carries gravity to the next rest: nothing is missed
    assert np.allclose(rows.y - rows.nominal, 0.0, atol=1e-9)
    # the rest after's directions are orthonormal: its coefficients are a rotation (° per rad)
    assert np.allclose(rows.to_coef.T @ rows.to_coef, np.degrees(1) ** 2 * np.eye(2))
    # moving the rest before by a (rad) along its first direction moves the miss by
    # −from_coef·a: the rows then read the move as turning gravity from there
    a = 1e-6
    start = up + a * attitude_basis(up)[0]
    moved = move_rows(t, rate, rate, start / np.linalg.norm(start), end, white)
    change = (moved.y - moved.nominal) - (rows.y - rows.nominal)
    assert np.allclose(change / a, -rows.from_coef[:, 0], rtol=1e-3, atol=1e-3)
