"""Several sim:// boards in one virtual cube (``cube=C&slot=K``, issue 45 item 2): given the
same hints they make the same motion, in host time too, and what they sense differs exactly
by each slot's mounting and lever arm."""

from __future__ import annotations

import time
from typing import cast

import numpy as np
import pytest
import serial

from host.transports.protocol_sim import Serial as SimSerial
from host.wire import sensor
from host.wire.frames import Frame
from host.wire.stream import StreamDecoder

if "host.transports" not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append("host.transports")

#: a perfect unit (nothing but the cube's place), exact clocks, no Earth rate
IDEAL = "truth=ideal&clock_ppm=0&sample_clock=0&earth_rate=0"
ACC_LSB = sensor.G0 / 16384.0


class Board:
    """A sim:// board with its decoded samples: true time (s, exact clocks), accel, gyro."""

    def __init__(self, url: str) -> None:
        self.port = cast(SimSerial, serial.serial_for_url(url, timeout=1.0))
        self.decoder = StreamDecoder()
        self.t = np.zeros(0)
        self.accel = np.zeros((0, 3))
        self.gyro = np.zeros((0, 3))

    def read_s(self, seconds: float) -> None:
        """Read about ``seconds`` of simulated samples (speed=max)."""
        frames: list[Frame] = self.decoder.feed(self.port.read(int(seconds * 50 * 27)))
        imu = [f.fields for f in frames if f.name == "IMU_SAMPLE"]
        counts = np.array([[f[k] for k in ("ax", "ay", "az", "gx", "gy", "gz")] for f in imu])
        self.t = np.concatenate([self.t, [f["t_us"] * 1e-6 for f in imu]])
        self.accel = np.concatenate([self.accel, sensor.accel_mps2(counts[:, :3])])
        self.gyro = np.concatenate([self.gyro, sensor.gyro_dps(counts[:, 3:])])

    def rotation(self) -> np.ndarray:
        """The board's mounting Rot(θ): v_cube = Rot(θ) @ v_board."""
        assert self.port.truth is not None
        return self.port.truth.mounting

    def between(self, a: float, b: float) -> np.ndarray:
        return (self.t >= a) & (self.t < b)


HINTS = (
    ("place", {"name": "x_up"}, 3.0),
    ("turn", {"axis": "z", "direction": "ccw", "turns": 1, "window_s": 7.0}, 7.5),
    ("place", {"name": "y_dn"}, 3.0),
    ("turn", {"axis": "y", "direction": "cw", "turns": 2, "window_s": 12.0}, 12.5),
)


def _sitting(urls: tuple[str, str]) -> tuple[list[Board], list[list[float]]]:
    """Two boards read unequal lengths first (their clocks apart), then every hint to both,
    each read on to the next: (boards, each board's ``now`` at each hint)."""
    boards = [Board(u) for u in urls]
    boards[0].read_s(1.0)
    boards[1].read_s(1.7)
    nows: list[list[float]] = [[], []]
    for action, kw, after in HINTS:
        for b, now in zip(boards, nows, strict=True):
            b.port.operator_hint(action, **kw)
            now.append(b.port.hints[-1][0])
        for b in boards:
            b.read_s(after)
    return boards, nows


@pytest.mark.slow
def test_two_boards_of_one_cube_sense_one_motion_apart_by_their_mounting_and_lever_arm() -> None:
    """Two perfect units in slots 1 and 6 of cube 4. At rest each reads gravity turned by its
    own mounting (Rot(θ)·reading is the same on both, to the LSB; the raw readings differ by
    g·θ). Through a turn the gyros' integrals, turned back by each mounting, agree (one motion:
    its angle, wobble and timing from each board's ``now``) while the raw ones differ by the
    turn's angle times the mountings' difference; the accelerometers' mean over the turn differs
    by the centripetal force of the slots' lever arms, −⟨ω²⟩·(r₁ − r₆) across the turn axis."""
    boards, nows = _sitting((f"sim://?cube=4&slot=1&seed=1&noise_seed=1&speed=max&{IDEAL}",
                             f"sim://?cube=4&slot=6&seed=2&noise_seed=2&speed=max&{IDEAL}"),
                            )  # fmt: skip
    assert abs(nows[1][0] - nows[0][0]) > 0.5  # the clocks really are apart
    rot = [b.rotation() for b in boards]
    for h, up in ((0, np.array([1.0, 0, 0])), (2, np.array([0, -1.0, 0]))):
        means = [b.accel[b.between(now[h] + 0.1, now[h] + 2.9)].mean(axis=0)
                 for b, now in zip(boards, nows, strict=True)]  # fmt: skip
        g = np.linalg.norm(means[0])
        for r, m in zip(rot, means, strict=True):
            assert np.max(np.abs(r @ m - g * up)) < 0.55 * ACC_LSB, (h, r @ m - g * up)
        assert np.max(np.abs(means[0] - means[1])) > 4 * ACC_LSB
    for h, axis, turns in ((1, 2, 1), (3, 1, 2)):
        sel = [
            b.between(now[h], now[h] + HINTS[h][1]["window_s"])
            for b, now in zip(boards, nows, strict=True)
        ]
        dt = [np.diff(b.t[s]).mean() for b, s in zip(boards, sel, strict=True)]
        turned = [
            r @ b.gyro[s].sum(axis=0) * d for r, b, s, d in zip(rot, boards, sel, dt, strict=True)
        ]
        raw = [b.gyro[s].sum(axis=0) * d for b, s, d in zip(boards, sel, dt, strict=True)]
        assert abs(abs(turned[0][axis]) - 360.0 * turns) < 0.5
        assert np.max(np.abs(turned[0] - turned[1])) < 0.05, turned[0] - turned[1]
        assert np.max(np.abs(raw[0] - raw[1])) > 0.5
        _centripetal_apart(boards, sel, rot, axis)


def _centripetal_apart(boards: list[Board], sel: list[np.ndarray], rot: list[np.ndarray],
                       axis: int) -> None:  # fmt: skip
    """Over a turn about cube axis ``axis``: mean accel (cube axes) of board 0 − board 1 across
    the axis is −⟨ω²⟩ times their lever arms' difference (the tangential ω̇×r averages out)."""
    omega2 = np.mean(np.sum(np.radians(boards[0].gyro[sel[0]]) ** 2, axis=1))
    mean = [r @ b.accel[s].mean(axis=0) for r, b, s in zip(rot, boards, sel, strict=True)]
    arms = [np.array(b.port.truth.lever_arm_m) for b in boards if b.port.truth is not None]
    across = [k for k in range(3) if k != axis]
    want = -omega2 * (arms[0] - arms[1])[across]
    got = (mean[0] - mean[1])[across]
    assert np.all(np.abs(want) > 0.05)  # the lever arms' difference is plain to see
    assert np.allclose(got, want, rtol=0.08, atol=0.01), (got, want)


def test_boards_of_one_cube_agree_in_host_time_to_the_gap_between_the_hints() -> None:
    """At 20× real time each board takes the turn hint at its own ``now``: the turn starts and
    ends at the same host time on both (``host_time_of``), within the wall time the two calls
    took, though the boards were opened apart."""
    a = cast(SimSerial, serial.serial_for_url("sim://?cube=8&slot=0&seed=1&speed=20", timeout=1))
    time.sleep(0.3)
    b = cast(SimSerial, serial.serial_for_url("sim://?cube=8&slot=3&seed=2&speed=20", timeout=1))
    a.read(200), b.read(200)
    t0 = time.monotonic()
    done = [p.operator_hint("turn", axis="x", direction="cw", turns=1) for p in (a, b)]
    span = time.monotonic() - t0
    for key in ("start_s", "end_s"):
        host = [p.host_time_of(d[key]) for p, d in zip((a, b), done, strict=True)]
        assert host[0] is not None and host[1] is not None
        assert abs(host[1] - host[0]) <= span + 1e-6, (key, host[1] - host[0], span)
    # the device times differ by how far apart the boards were opened: 20 × 0.3 s, less the
    # time between the calls
    assert done[0]["start_s"] - done[1]["start_s"] > 2.0
    assert a.host_time_of(1.0) is not None
    assert cast(SimSerial, serial.serial_for_url("sim://?speed=max")).host_time_of(1.0) is None


@pytest.mark.parametrize("query", ["slot=3", "cube=1&slot=8", "cube=x", "cube=1&slot=-1"])
def test_bad_cube_or_slot_is_one_line_naming_it(query: str) -> None:
    with pytest.raises(serial.SerialException) as err:
        serial.serial_for_url(f"sim://?{query}")
    text = str(err.value)
    assert "\n" not in text and ("slot" in text if "slot" in query else "cube" in text)
