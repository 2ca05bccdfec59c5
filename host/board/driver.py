"""The board driver: a connected board as the live calibration needs it.

:class:`Board` opens a port by URL (:func:`host.board.link.open_port`), waits for HELLO and
checks it (:mod:`host.board.hello`: one wait, one spec check), reads frames with host arrival
times, feeds every IMU sample to the live device→host clock estimate
(:class:`host.timing.clock.LiveClock`), sends commands (PING, START_STREAM, GET_CONFIG),
runs the MPU-6000 self-test (:meth:`Board.self_test`, judged by :mod:`host.wire.selftest`),
survives reconnects and records one measurement on device time (:meth:`Board.acquire`, the
window cut by :mod:`host.board.acquisition`). It decodes with the spec's codecs
(:func:`host.wire.frames.sample_t_us`) and unwraps device time by the counters' rules of
:mod:`host.wire.segments`; :meth:`Board.physical` turns counts into m/s², °/s and °C with the
full scales HELLO reported (:mod:`host.wire.sensor`). :class:`BoardInfo` is what HELLO says,
:func:`default_port` finds a board among the serial ports.

The dialogue that asks the operator (:mod:`host.dialogue.flow`) drives a Board; nothing here
talks to the operator.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import serial
from serial.serialutil import Timeout

from host.board.acquisition import SAMPLE_STALL_S, Acquisition, acquire, acquire_all
from host.board.hello import check_spec, wait_for_hello
from host.board.link import DEFAULT_BAUD, Link, LinkTimeout, open_port
from host.errors import UserError
from host.timing.clock import LiveClock, serialisation_ns
from host.wire import protocol_gen as gen
from host.wire import sensor
from host.wire.capture import MAGIC, CaptureWriter, create_capture_file
from host.wire.frames import (
    IMU_SAMPLE,
    MESSAGES,
    OVERHEAD,
    Frame,
    error_text,
    sample_t_us,
    status_text,
)
from host.wire.segments import t_us_step, t_us_went_back
from host.wire.selftest import SelfTest, judge

#: the spec this host speaks (HELLO.spec_fingerprint must match)
HOST_SPEC_FINGERPRINT = gen.SPEC_FINGERPRINT
#: no bytes at all from the port for this long is a silent board (LinkTimeout), s
STALL_S = 2.0
#: bytes of one IMU_SAMPLE frame on the wire (for its serialisation time)
IMU_FRAME_BYTES = MESSAGES[IMU_SAMPLE].length + OVERHEAD
#: the self-test takes ≈ 1.3 s on the board; give up on its result after this long, s
SELF_TEST_TIMEOUT_S = 6.0
#: a board still bringing its sensor up answers SELF_TEST with BUSY: ask again after this, s
SELF_TEST_RETRY_S = 0.25
_ACK_STATUS = gen.ENUMS["ack_status"]
#: USB vendor ids of boards that look like an APM 2.6 (Arduino Mega 2560 / 16U2, FTDI)
APM_VIDS = (0x2341, 0x2A03, 0x0403)
_APM_WORDS = ("arduino mega", "atmega16u2", "apm", "ardupilot", "mega 2560")


def default_port(comports: Callable[[], Iterable[Any]] | None = None) -> tuple[str, str | None]:
    """The first USB serial port that looks like an APM (Arduino Mega 2560 / ATmega16U2 / FTDI),
    else ``sim://``. Returns (port, note to print or None)."""
    if comports is None:
        from serial.tools import list_ports

        comports = list_ports.comports
    try:
        ports = list(comports())
    except Exception:  # noqa: BLE001 - enumeration problems must not stop the program
        ports = []
    for p in ports:
        vid = getattr(p, "vid", None)
        words = " ".join(
            str(getattr(p, a, "") or "") for a in ("description", "product", "manufacturer")
        ).lower()
        if vid in APM_VIDS or any(w in words for w in _APM_WORDS):
            return str(p.device), f"using the board on {p.device}"
    looked = ", ".join(str(p.device) for p in ports) or "no serial ports at all"
    return "sim://", (
        f"NO BOARD FOUND (looked at: {looked}): using the VIRTUAL board sim:// — a simulated "
        "sensor, not a unit. Plug in the APM or give --port"
    )


@dataclass(frozen=True)
class BoardInfo:
    """What HELLO says about the board."""

    firmware: str
    protocol_version: int
    spec_fingerprint: int
    who_am_i: int
    accel_fs_sel: int
    gyro_fs_sel: int
    dlpf_cfg: int
    smplrt_div: int
    streaming: bool
    reset_cause: int
    baud: int = DEFAULT_BAUD
    product_id: int | None = None  # the revision: C4/C5 count half the accelerometer LSB/g

    @classmethod
    def from_hello(cls, f: dict[str, int]) -> BoardInfo:
        return cls(
            firmware=f"{f['fw_major']}.{f['fw_minor']}.{f['fw_patch']}",
            protocol_version=f["protocol_version"],
            spec_fingerprint=f["spec_fingerprint"],
            who_am_i=f["who_am_i"],
            accel_fs_sel=f["accel_fs_sel"],
            gyro_fs_sel=f["gyro_fs_sel"],
            dlpf_cfg=f["dlpf_cfg"],
            smplrt_div=f["smplrt_div"],
            streaming=bool(f["streaming"]),
            reset_cause=f["reset_cause"],
            baud=f["baud"] or DEFAULT_BAUD,
            product_id=f.get("product_id"),
        )

    @property
    def rate_hz(self) -> float:
        """Nominal output rate, Hz: internal rate (8 kHz with DLPF 0/7, else 1 kHz) / (1+div)."""
        internal = 8000.0 if self.dlpf_cfg in (0, 7) else 1000.0
        return internal / (1 + self.smplrt_div)

    @property
    def accel_range_g(self) -> int:
        return sensor.accel_range_g(self.accel_fs_sel, self.product_id)

    @property
    def accel_lsb_per_g(self) -> float:
        """Accelerometer sensitivity of this part at its AFS_SEL, LSB/g (C4/C5: halved)."""
        return sensor.accel_lsb_per_g(self.accel_fs_sel, self.product_id)

    @property
    def gyro_range_dps(self) -> int:
        return sensor.GYRO_RANGE_DPS.get(self.gyro_fs_sel, 0)

    @property
    def gyro_alarm_counts(self) -> int:
        """|count| at or above which a gyro sample is out of the working range: range − 1 LSB."""
        return int(math.ceil(self.gyro_range_dps * sensor.GYRO_LSB_PER_DPS[self.gyro_fs_sel])) - 1

    def describe(self) -> str:
        who = "MPU-6000" if self.who_am_i == sensor.WHO_AM_I_MPU6000 else "not an MPU-6000!"
        return (
            f"firmware {self.firmware}, protocol {self.protocol_version} "
            f"(spec {self.spec_fingerprint:#010x}), WHO_AM_I {self.who_am_i:#04x} ({who}) "
            f"rev {sensor.revision_name(self.product_id)}, "
            f"accel ±{self.accel_range_g} g, gyro ±{self.gyro_range_dps} °/s, "
            f"DLPF_CFG {self.dlpf_cfg}, SMPLRT_DIV {self.smplrt_div} ({self.rate_hz:g} Hz)"
        )

    def meta(self) -> dict[str, str]:
        return {
            "firmware": self.firmware,
            "protocol_version": str(self.protocol_version),
            "spec_fingerprint": f"{self.spec_fingerprint:#010x}",
            **sensor.identity_meta(self.who_am_i, self.product_id),
            "accel_range_g": str(self.accel_range_g),
            "gyro_range_dps": str(self.gyro_range_dps),
            "dlpf_cfg": str(self.dlpf_cfg),
            "smplrt_div": str(self.smplrt_div),
            "sample_rate_hz": f"{self.rate_hz:g}",
        }


class DeferredCapture(CaptureWriter):
    """An IMUCAP01 writer that keeps the reads in memory until :meth:`start` names the file
    (the port is opened before the serial number, which names the file, is known)."""

    def __init__(self) -> None:  # no file yet: CaptureWriter.__init__ is not called
        self.path = Path()
        self._f = None
        self._held: list[tuple[int, bytes]] = []
        self._held_bytes = 0

    def write(self, t_ns: int, data: bytes) -> None:
        if self._f is not None:
            super().write(t_ns, data)
        elif data and self._held_bytes < 16 << 20:
            self._held.append((t_ns, bytes(data)))
            self._held_bytes += len(data)

    def start(self, path: Path) -> None:
        """Create ``path`` and write what was held so far."""
        self.path = path
        self._f = create_capture_file(path)  # never over an earlier capture
        self._f.write(MAGIC)
        held, self._held = self._held, []
        for t_ns, data in held:
            super().write(t_ns, data)

    @property
    def started(self) -> bool:
        return self._f is not None


class Board:
    """The connected board: opens the port, checks HELLO, reads frames, survives reconnects.

    ``port_factory(url)`` opens the port (default :func:`host.board.link.open_port`); re-connecting
    re-opens the *same* port object (``close()`` + ``open()``), which is what a USB serial
    device needs after it re-appears and what ``sim://`` supports after ``pull_cable``.
    """

    def __init__(
        self,
        url: str,
        port_factory: Callable[[str], serial.SerialBase] | None = None,
        stall_s: float = STALL_S,
        warn: Callable[[str], None] | None = None,
        hello_timeout_s: float = 5.0,
        sample_stall_s: float = SAMPLE_STALL_S,
    ) -> None:
        self.url = url
        self.hello_timeout_s = hello_timeout_s
        self.sample_stall_s = sample_stall_s
        self.port_factory = port_factory or (lambda u: open_port(u, DEFAULT_BAUD))
        self.stall_s = stall_s
        self.capture = DeferredCapture()
        self.warn: Callable[[str], None] = warn or (lambda s: None)
        self.link: Link | None = None
        self.info: BoardInfo | None = None
        self._errors_seen: set[tuple[int, int]] = set()
        self._status_flags_seen = 0  # STATUS.flags bits already shown
        #: flags of the newest STATUS since the last HELLO (None: none yet)
        self.status_flags: int | None = None
        self.clock = LiveClock()
        self._clock_last_t: int | None = None  # raw t_us of the last sample fed to the clock
        self._clock_dev_us = 0  # its unwrapped value
        self._ping_nonce = 0
        #: the last self-test's outcome (None: not run on this board)
        self.self_test_result: SelfTest | None = None

    # ---- connection ----------------------------------------------------------------------
    def connect(self) -> BoardInfo:
        """Open the port and wait for HELLO (UserError if it cannot be opened)."""
        port = self.port_factory(self.url)
        self._attach(port)
        return self.await_hello()

    def reopen(self) -> BoardInfo:
        """Close and re-open the same port, then wait for HELLO. Raises SerialException /
        OSError while the device is absent, LinkTimeout if it says nothing."""
        assert self.link is not None
        port: Any = self.link.port
        try:
            port.close()
        except (serial.SerialException, OSError):
            pass
        port.open()
        self._attach(port)
        return self.await_hello()

    def _attach(self, port: serial.SerialBase) -> None:
        self.restart_clock()
        link = Link(port, capture=None, stall_s=self.stall_s)
        link.capture = self.capture  # one capture over the whole session, across reconnects
        self.link = link

    def close(self) -> None:
        if self.link is not None:
            self.link.close()  # closes the capture too
        else:
            self.capture.close()

    @property
    def port(self) -> Any:
        assert self.link is not None
        return self.link.port

    def hint(self, action: str, **kw: Any) -> dict[str, Any] | None:
        """Tell a virtual bench what the operator is asked (no-op on a real board)."""
        fn = getattr(self.port, "operator_hint", None) if self.link is not None else None
        if fn is None:
            return None
        result = fn(action, **kw)
        return result if isinstance(result, dict) else None

    @property
    def has_operator(self) -> bool:
        """True when the port moves the cube itself (virtual bench)."""
        return self.link is not None and hasattr(self.port, "operator_hint")

    def await_hello(self, timeout_s: float | None = None) -> BoardInfo:
        """Read until HELLO (asking with GET_CONFIG if it does not come,
        :func:`host.board.hello.wait_for_hello`); check it. ``timeout_s`` default:
        ``hello_timeout_s`` (a real board's bootloader takes ~1-2 s)."""
        assert self.link is not None
        timeout_s = self.hello_timeout_s if timeout_s is None else timeout_s
        try:
            _, f, _ = wait_for_hello(
                self.link, timeout_s, read=self.read_frames, port_name=self.url
            )
        except LinkTimeout as exc:
            raise LinkTimeout(f"{exc}: is the firmware flashed? (python3 -m host flash)") from None
        return self._accept_hello(f)

    def _accept_hello(self, f: Frame) -> BoardInfo:
        assert self.link is not None
        info = BoardInfo.from_hello(f.fields)
        check_spec(
            info.spec_fingerprint,
            who="the firmware",
            remedy="flash the matching firmware (python3 -m host flash)",
            protocol_version=info.protocol_version,
        )
        if info.who_am_i in (0x00, 0xFF):
            raise UserError(
                f"the board reads WHO_AM_I {info.who_am_i:#04x}: no sensor answers on SPI; "
                "check the IMU (an MPU-6000 reads 0x68)"
            )
        if info.gyro_fs_sel not in sensor.GYRO_LSB_PER_DPS or (
            info.accel_fs_sel not in sensor.ACCEL_LSB_PER_G
        ):
            raise UserError(f"the board reports impossible full-scale settings: {info}")
        if not info.streaming:
            self.link.send("START_STREAM")
        unknown = sensor.revision_warning(info.product_id)
        if unknown and (self.info is None or self.info.product_id != info.product_id):
            self.warn(unknown)  # once per part, not at every restart
        self.info = info
        return info

    # ---- time ----------------------------------------------------------------------------
    def restart_clock(self) -> None:
        """Forget the device→host clock estimate (the board restarted: a new device clock)."""
        self.clock = LiveClock()
        self._clock_last_t = None

    def _feed_clock(self, arrival_ns: int, t_us: int) -> None:
        """One sample for the live clock map: unwrapped device µs vs arrival minus the time
        the UART needed to send the frame (host.timing.clock, eq. 1)."""
        if self._clock_last_t is not None:
            d = int(t_us_step(self._clock_last_t, t_us))
            if t_us_went_back(d):  # the board restarted
                self.restart_clock()
            else:
                self._clock_dev_us += d
        if self._clock_last_t is None:
            self._clock_dev_us = t_us
        self._clock_last_t = t_us
        baud = self.info.baud if self.info is not None else DEFAULT_BAUD
        floor = arrival_ns - float(serialisation_ns(IMU_FRAME_BYTES, baud))
        self.clock.add(self._clock_dev_us, floor)

    def power_on_s(self, t_us_start: int) -> float | None:
        """Device time of the sample with raw ``t_us_start`` since the board's last reset
        (its power-on: the board restarts when the port opens), s, from the unwrapped clock
        fed by every sample; None before any sample."""
        if self._clock_last_t is None:
            return None
        back = int(t_us_step(t_us_start, self._clock_last_t))
        return (self._clock_dev_us - back) / 1e6

    def clock_meta(self, t_us_start: int) -> dict[str, str]:
        """The live clock map as record metadata (empty until it has an estimate)."""
        m = self.clock.map
        if m is None or self._clock_last_t is None:
            return {}
        back = int(t_us_step(t_us_start, self._clock_last_t))
        host_at_start = float(m.to_host_ns(self._clock_dev_us - back))
        return {
            "clock_host_ns_at_start": str(int(round(host_at_start))),
            "clock_skew_ppm": f"{m.skew_ppm:.2f}",
            "clock_points": str(m.points),
            "clock_latency_median_us": f"{m.latency_median_us:.0f}",
            "clock_floor_spread_us": f"{m.floor_spread_us:.0f}",
        }

    # ---- reading -------------------------------------------------------------------------
    def read_frames(self) -> list[tuple[int, Frame]]:
        """One read of the port: (host ns of the read, frame) for each frame it completed.
        Every IMU sample also feeds the live clock estimate."""
        assert self.link is not None
        t_ns, data = self.link.read_chunk()
        if not data:
            return []
        out = [(t_ns, f) for f in self.link.decoder.feed(data)]
        for arrival_ns, f in out:
            if f.type == IMU_SAMPLE:
                self._feed_clock(arrival_ns, sample_t_us(f.payload))
            elif f.name == "HELLO":
                self.restart_clock()
                self.status_flags = None  # a restarted firmware reads at 8 MHz again
            elif f.name == "STATUS":
                flags = self.status_flags = int(f.fields["flags"])
                if flags & ~self._status_flags_seen:
                    self._status_flags_seen |= flags  # shown once, whenever it comes
                    self.warn(status_text(f) or f"the board reports STATUS flags {flags}")
        return out

    def pump(self) -> None:
        """Read and drop samples (between measurements); report ERROR frames and resets."""
        for _, f in self.read_frames():
            if f.type != IMU_SAMPLE:
                self.report_frame(f)

    def report_frame(self, f: Frame) -> None:
        """An ERROR (once per code and detail) or HELLO (the board restarted) frame seen
        outside the samples: warn, and accept a new HELLO."""
        if f.name == "ERROR":
            fl = f.fields
            key = (fl["code"], fl["detail"])
            if key not in self._errors_seen:
                self._errors_seen.add(key)
                self.warn(f"the board reports {error_text(f)}")
        elif f.name == "HELLO":
            info = self._accept_hello(f)
            self.warn(f"the board restarted (reset cause {info.reset_cause:#04x})")

    def acquire(
        self,
        duration_s: float,
        tick: Callable[[float, np.ndarray, int], None] | None = None,
        check_escape: Callable[[], bool] | None = None,
        tick_every_s: float = 0.1,
        enough: Callable[[np.ndarray, float], bool] | None = None,
    ) -> Acquisition:
        """Record ``duration_s`` seconds of device time from now (the start beep): the window
        cut on device time by :func:`host.board.acquisition.acquire` (its PONG, losses, resets
        and stalls), ``tick``, ``check_escape`` and ``enough`` (an early end) as there."""
        assert self.link is not None and self.info is not None
        return acquire(
            self, self.info.rate_hz, self.next_nonce(), duration_s, tick, check_escape,
            tick_every_s, enough,
        )  # fmt: skip

    def next_nonce(self) -> int:
        """The nonce of the next measurement's PING (its PONG names it)."""
        self._ping_nonce = (self._ping_nonce + 1) & 0xFFFFFFFF
        return self._ping_nonce

    def self_test(self, timeout_s: float = SELF_TEST_TIMEOUT_S) -> SelfTest:
        """Run the MPU-6000 self-test: SELF_TEST, its ACK, then SELF_TEST_RESULT judged by
        :func:`host.wire.selftest.judge` (kept in :attr:`self_test_result`). The board sends
        no samples meanwhile; keep the unit still. BUSY (the sensor is still coming up) is
        asked again every :data:`SELF_TEST_RETRY_S`; UNSUPPORTED (a DMP build) or no result
        within ``timeout_s`` give a self-test without verdict that says why."""
        assert self.link is not None and self.info is not None
        timeout = Timeout(timeout_s)
        seq = self.link.send("SELF_TEST")
        retry: Timeout | None = None
        result: SelfTest | None = None
        while result is None and not timeout.expired():
            if retry is not None and retry.expired():
                seq, retry = self.link.send("SELF_TEST"), None
            for _, f in self.read_frames():
                if f.name == "SELF_TEST_RESULT" and retry is None:
                    result = judge(f.fields, self.info.product_id)
                elif f.name == "ACK" and f.fields["cmd_seq"] == seq:
                    status = f.fields["status"]
                    if status == _ACK_STATUS["BUSY"]:
                        retry = Timeout(SELF_TEST_RETRY_S)
                    elif status != _ACK_STATUS["OK"]:
                        result = SelfTest("", "the firmware does not run it (a DMP build?)", (), 0)
                elif f.type != IMU_SAMPLE:
                    self.report_frame(f)
        if result is None:
            result = SelfTest("", f"no self-test result within {timeout_s:g} s", (), 0)
        self.self_test_result = result
        return result

    # ---- units ---------------------------------------------------------------------------
    def physical(self, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(N,7) counts -> accel (N,3) m/s², gyro (N,3) °/s, temp (N,) °C."""
        assert self.info is not None
        c = np.asarray(counts).reshape(-1, 7)
        a = sensor.accel_mps2(c[:, 0:3], self.info.accel_fs_sel, self.info.product_id)
        g = sensor.gyro_dps(c[:, 4:7], self.info.gyro_fs_sel)
        t = sensor.temp_c(c[:, 3])
        return a, g, t


def acquire_boards(
    boards: Sequence[Board],
    duration_s: float,
    tick: Callable[[float, np.ndarray, int], None] | None = None,
    check_escape: Callable[[], bool] | None = None,
    enough: Callable[[np.ndarray, float], bool] | None = None,
) -> list[Acquisition]:
    """One measurement of ``duration_s`` s on every board of ``boards`` at once, from one
    start beep (:func:`host.board.acquisition.acquire_all`: each board's window on its own
    device time from its PONG; a failure is :class:`host.board.acquisition.BoardFailed`
    naming the board; ``enough`` as :meth:`Board.acquire` says, for one board)."""
    for b in boards:
        assert b.link is not None and b.info is not None
    each = [(b, b.info.rate_hz, b.next_nonce()) for b in boards if b.info is not None]
    return acquire_all(each, duration_s, tick, check_escape, enough=enough)
