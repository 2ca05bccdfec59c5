"""The virtual firmware: what the board's firmware does on the wire, simulated byte in, byte out.

A :class:`VirtualFirmware` is one power-up of the virtual board: the simulated MPU-6000 on the
cube (:class:`host.bench.sim.Simulator`) read at its sample rate, and the firmware's protocol
behaviour (protocol/messages.md) around it. Host bytes go in with :meth:`~VirtualFirmware.receive`
(command frames, any chunking; bad CRCs are counted in STATUS.crc_errors); device bytes come
out of :attr:`~VirtualFirmware.output` as simulated time is run forward with
:meth:`~VirtualFirmware.run_until`:

- at power-up: HELLO (this host's spec fingerprint, the reset cause), then IMU_SAMPLE frames at
  50 Hz (device time in µs from the MCU timer, 0.5 µs resolution) and STATUS once a second, one
  ``seq`` counter over all frames;
- PING → PONG (device time now) + ACK; START_STREAM / STOP_STREAM → ACK; SET_RATE → ACK (the
  samples after it carry CONFIG_CHANGED; DLPF_CFG > 6 or a rate above 500 Hz → ACK
  BAD_ARGUMENT); GET_CONFIG → HELLO + ACK; GET_STATUS → STATUS + ACK; SELF_TEST → ACK, no
  samples for :data:`SELF_TEST_S`, then SELF_TEST_RESULT (the windows as the firmware takes
  them, the part answering as ``self_test=pass|fail`` says: :class:`SelfTestPart`) and samples
  again, the first with CONFIG_CHANGED; anything else → ACK UNSUPPORTED + ERROR BAD_COMMAND.

It knows nothing of ports, wall clocks or cables: the ``sim://`` adapter
(:mod:`host.transports.protocol_sim`) paces it, delivers its bytes and pulls the cable.
"""

from __future__ import annotations

import numpy as np

from host.bench.physics import Bench, Environment, Motion
from host.bench.sim import Simulator
from host.bench.truth import SensorTruth
from host.wire import protocol_gen as gen
from host.wire.frames import encode_frame, encode_imu_samples
from host.wire.selftest import ACCEL_FS_SEL, accel_factory_trim, gyro_factory_trim, trim_codes
from host.wire.sensor import ACCEL_LSB_PER_G, DEFAULT_PRODUCT_ID, accel_lsb_per_g
from host.wire.stream import StreamDecoder

FW_VERSION = (0, 1, 0)
BAUD = 115200
DEFAULT_DLPF = 4  # as the firmware: ≈20 Hz bandwidth at 1 kHz internal rate
DEFAULT_SMPLRT_DIV = 19  # 1 kHz / (1 + 19) = 50 Hz
TIMER_RESOLUTION_NS = 500  # as the firmware: Timer1 at fosc/8
MAX_RATE_HZ = 500.0
#: reset causes in HELLO: power-on, and the reset the host's DTR gives when it opens the port
RESET_POWER_ON, RESET_EXTERNAL = 1, 2
ERROR_BAD_COMMAND = gen.ENUMS["error_code"]["BAD_COMMAND"]
_ACK = gen.ENUMS["ack_status"]
#: the self-test's course as the firmware runs it, s from the command: (end, window) — the
#: response settles 0.1 s, then 32 samples at 100 Hz are averaged; off, on, off again
SELF_TEST_SCHEDULE = (
    (0.10, ""), (0.42, "off"), (0.52, ""), (0.84, "on"), (0.94, ""), (1.26, "end"),
)  # fmt: skip
SELF_TEST_S = SELF_TEST_SCHEDULE[-1][0]


class SelfTestPart:
    """How the virtual chip answers its self-test: its SELF_TEST_X/Y/Z/A registers (the
    emulated chip's) and each axis' response relative to the factory trim those hold — within
    a few % (``fail=False``), or accelerometer Y 35 % above and gyroscope Z 45 % below it
    (``fail=True``; the part fails: ±14 % is allowed)."""

    REGISTERS = (0x4C, 0x4D, 0x6A, 0x56)
    HEALTHY = (0.021, -0.034, 0.012, -0.015, 0.026, -0.022)  # ax ay az gx gy gz

    def __init__(self, fail: bool = False) -> None:
        dev = list(self.HEALTHY)
        if fail:
            dev[1], dev[5] = 0.35, -0.45
        self.deviation = tuple(dev)

    def response_counts(self, product_id: int) -> np.ndarray:
        """(6,) the response in counts at ±8 g / ±250 °/s (ax ay az gx gy gz) of a part with
        ``product_id`` (C4/C5 count half the accelerometer's)."""
        accel, gyro = trim_codes(*self.REGISTERS)
        gain = accel_lsb_per_g(ACCEL_FS_SEL, product_id) / ACCEL_LSB_PER_G[ACCEL_FS_SEL]
        ft = [gain * accel_factory_trim(c) for c in accel]
        ft += [gyro_factory_trim(c, i) for i, c in enumerate(gyro)]
        return np.array(ft) * (1.0 + np.array(self.deviation))


def hello_fields(
    dlpf: int = DEFAULT_DLPF,
    div: int = DEFAULT_SMPLRT_DIV,
    reset_cause: int = RESET_POWER_ON,
    streaming: bool = True,
    product_id: int = DEFAULT_PRODUCT_ID,
) -> dict[str, int]:
    """The fields of the virtual board's HELLO frame (this host's spec, ±2 g, ±250 °/s;
    ``product_id``: the chip's revision)."""
    return dict(
        fw_major=FW_VERSION[0],
        fw_minor=FW_VERSION[1],
        fw_patch=FW_VERSION[2],
        protocol_version=gen.PROTOCOL_VERSION,
        spec_fingerprint=gen.SPEC_FINGERPRINT,
        who_am_i=0x68,
        product_id=product_id,
        accel_fs_sel=0,
        gyro_fs_sel=0,
        dlpf_cfg=dlpf,
        smplrt_div=div,
        mode=0,
        timer_resolution_ns=TIMER_RESOLUTION_NS,
        baud=BAUD,
        reset_cause=reset_cause,
        streaming=int(streaming),
    )


class VirtualFirmware:
    """One power-up of the virtual board: host bytes in (:meth:`receive`), device bytes out
    (:attr:`output`, filled by :meth:`run_until`). ``power_on_s``: time since the board was
    powered, s (a reset without a power cycle keeps the chip warm); ``pose``: where the cube
    is at the reset; ``product_id`` the chip's revision (``revision=``)."""

    def __init__(
        self,
        truth: SensorTruth,
        bench: Bench,
        environment: Environment,
        seed: np.random.SeedSequence,
        power_on_s: float,
        pose: Motion,
        reset_cause: int = RESET_POWER_ON,
        product_id: int = DEFAULT_PRODUCT_ID,
        self_test_part: SelfTestPart | None = None,
    ) -> None:
        self.environment = environment
        self.self_test_part = self_test_part or SelfTestPart()
        #: a self-test in progress: its start (s since the reset) and each window's samples
        self._self_test: tuple[float, dict[str, list[np.ndarray]]] | None = None
        self.sim = Simulator(truth, bench, environment, seed, 50.0, power_on_s)
        self.sim.product_id = product_id  # the chip revision (HELLO, and its accel scale)
        self.sim.set_motion(pose, 0.0)
        #: device bytes not yet delivered to the host
        self.output = bytearray()
        self._decoder = StreamDecoder("any")  # as the firmware: any type
        self._seq = 0
        #: simulated seconds since the reset up to which output has been produced
        self.t_s = 0.0
        self._next_status_s = 1.0
        self.streaming = True
        self.dlpf = DEFAULT_DLPF
        self.div = DEFAULT_SMPLRT_DIV
        self.reset_cause = reset_cause
        self._bad_commands = 0
        self._emit("HELLO", **self.hello_fields())

    # ---- device → host -----------------------------------------------------------------
    def _emit(self, msg: str, **fields: int) -> None:
        self.output += encode_frame(msg, self._seq, **fields)
        self._seq = (self._seq + 1) & 0xFFFF

    def hello_fields(self) -> dict[str, int]:
        """The fields of this board's HELLO frame now."""
        return hello_fields(
            self.dlpf, self.div, self.reset_cause, self.streaming, self.sim.product_id
        )

    def status_fields(self) -> dict[str, int]:
        """The fields of a STATUS frame now."""
        uptime_us = int(self.environment.device_us(np.array([self.t_s]))[0])
        return dict(
            uptime_ms=(uptime_us // 1000) & 0xFFFFFFFF,
            samples=self.sim.samples & 0xFFFFFFFF,
            missed=0,
            dropped=0,
            crc_errors=min(self._decoder.stats.crc_errors, 0xFFFF),
            spi_faults=0,
            fifo_overflows=0,
            tx_queue_max=7,
            bad_bursts=0,
            flags=0,
        )

    def run_until(self, t_s: float) -> None:
        """Produce every frame up to ``t_s`` simulated seconds since the reset."""
        while self.t_s < t_s:
            t_stop = min(t_s, self._next_status_s)
            if self._self_test is not None:
                t_stop = self._self_test_step(t_stop)
            else:
                block = self.sim.run_until(t_stop)
                if self.streaming and len(block):
                    self.output += encode_imu_samples(
                        self._seq, block.t_us, block.counts, block.flags
                    )
                    self._seq = (self._seq + len(block)) & 0xFFFF
            self.t_s = t_stop
            if t_stop >= self._next_status_s:
                self._emit("STATUS", **self.status_fields())
                self._next_status_s += 1.0

    def _self_test_step(self, t_stop: float) -> float:
        """Run the self-test on to ``t_stop`` or the next window's end, whichever is first;
        at its end send SELF_TEST_RESULT. -> the time reached."""
        assert self._self_test is not None
        start, windows = self._self_test
        end, name = next((start + e, n) for e, n in SELF_TEST_SCHEDULE if start + e > self.t_s)
        t = min(t_stop, end)
        block = self.sim.run_until(t)
        if name and len(block):
            counts = block.counts[:, [0, 1, 2, 4, 5, 6]].astype(float)
            counts[:, :3] /= ACCEL_LSB_PER_G[0] / ACCEL_LSB_PER_G[ACCEL_FS_SEL]  # ±2 g -> ±8 g
            if name == "on":
                counts += self.self_test_part.response_counts(self.sim.product_id)
            windows.setdefault(name, []).append(counts)
        if t >= start + SELF_TEST_S:
            self._self_test = None
            self._emit("SELF_TEST_RESULT", **self._self_test_fields(windows))
            self.sim.set_rate(self.sim.rate_hz)  # restored: the next sample says CONFIG_CHANGED
        return t

    def _self_test_fields(self, windows: dict[str, list[np.ndarray]]) -> dict[str, int]:
        x, y, z, a = SelfTestPart.REGISTERS
        fields = dict(status=0, self_test_x=x, self_test_y=y, self_test_z=z, self_test_a=a)
        for w in ("off", "on", "end"):
            c = np.concatenate(windows[w])
            fields["samples"] = len(c)
            for name, v in zip(("ax", "ay", "az", "gx", "gy", "gz"), c.mean(axis=0), strict=True):
                fields[f"{name}_{w}"] = int(np.clip(np.rint(v), -32768, 32767))
        return fields

    # ---- host → device -----------------------------------------------------------------
    def receive(self, data: bytes) -> None:
        """Host bytes (command frames in any chunking), answered at the current time."""
        for frame in self._decoder.feed(data):
            self._handle(frame.type, frame.seq, frame.fields)

    def _handle(self, mtype: int, cmd_seq: int, fields: dict[str, int]) -> None:
        name = gen.MESSAGES[mtype][0] if mtype in gen.MESSAGES else ""
        status = _ACK["OK"]
        if name == "PING":
            t_us = int(self.environment.device_us(np.array([self.t_s]))[0])
            self._emit("PONG", nonce=fields["nonce"], t_us=t_us & 0xFFFFFFFF)
        elif name == "START_STREAM":
            self.streaming = True
        elif name == "STOP_STREAM":
            self.streaming = False
        elif name == "SET_RATE":
            div, dlpf = fields["smplrt_div"], fields["dlpf_cfg"]
            internal = 8000.0 if dlpf in (0, 7) else 1000.0
            rate = internal / (1 + div)
            if dlpf > 6 or rate > MAX_RATE_HZ:
                status = _ACK["BAD_ARGUMENT"]
            else:
                self.div, self.dlpf = div, dlpf
                self.sim.set_rate(rate)
        elif name == "GET_CONFIG":
            self._emit("HELLO", **self.hello_fields())
        elif name == "GET_STATUS":
            self._emit("STATUS", **self.status_fields())
        elif name == "SELF_TEST":
            if self._self_test is not None:
                status = _ACK["BUSY"]
            else:
                self._self_test = (self.t_s, {})
        else:
            status = _ACK["UNSUPPORTED"]
        self._emit("ACK", cmd_type=mtype, cmd_seq=cmd_seq, status=status)
        if status == _ACK["UNSUPPORTED"]:  # as the firmware: an ERROR frame follows the ACK
            self._bad_commands += 1
            self._emit("ERROR", code=ERROR_BAD_COMMAND, detail=mtype, count=self._bad_commands)
