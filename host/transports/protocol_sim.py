"""``sim://`` — a virtual APM 2.6 board (MPU-6000 on the calibration cube) as a pyserial port.

URL grammar (all options optional, ``&``-separated; ``operator_fault`` and ``fault`` may repeat;
the options shared with ``emu://`` are read by :mod:`host.bench.options`)::

    sim://[?seed=N][&noise_seed=N][&serial=S][&speed=realtime|N|max][&operator=auto|manual][&truth=random|ideal]
          [&operator_fault=wrong_face[@K]|incomplete_turn[@K]|too_fast[@K]]...
          [&fault=pull_cable[@SECONDS]|wrong_face[@K]|incomplete_turn[@K]|too_fast[@K]]...
          [&clock_ppm=PPM][&sample_clock=REL][&latitude=DEG][&tilt=DEG][&earth_rate=0|1]
          [&effects=NAME,NAME...][&chamber=FROM:TO:MINUTES[@START_S]][&revision=D8|C4|C5|...]
          [&self_test=pass|fail][&cube=C[&slot=K]]

- ``seed`` (default: from ``serial``, :func:`host.bench.options.unit_seed`, else 0): draws the
  unit — its truth and its room/clock; same seed, same board. ``serial``: the unit's serial
  number (the dialogue adds ``--serial``'s). ``noise_seed``: draws the noise and the operator's
  hand; not given, they are fresh in every session (a repeat of the unit, as on a real bench).
- ``speed``: ``realtime`` (default) — simulated time follows the wall clock; ``N`` — it runs N×
  faster; ``max`` — time advances only as bytes are read: ``read(n)`` returns n bytes at once.
- ``truth``: ``random`` (default, :meth:`SensorTruth.random`) or ``ideal`` (no errors at all);
  ``effects`` keeps only those effects of the truth (e.g. ``effects=linear,noise``).
- ``clock_ppm``: MCU µs timer error; ``sample_clock``: sensor sample-clock error, relative
  (0.004 = 50.2 Hz). Default: drawn from the seed. ``latitude``, ``tilt`` (base tilt about the
  east axis) and ``earth_rate`` set up the bench.
- ``chamber``: a thermal chamber ramps the air from FROM to TO °C over MINUTES, starting
  START_S simulated seconds after power-on (default 0), then holds; the chip's warm-up rides
  on top (e.g. ``chamber=-10:50:60`` for a thermal calibration).
- ``revision``: the MPU-6000's PRODUCT_ID, reported in HELLO: ``D8`` (default), ``C4``/``C5``
  (half the accelerometer LSB/g: the counts say so), ``D6`` … ``D10``, or a number (``0x55``).
- ``self_test``: how the chip answers the MPU-6000 self-test (SELF_TEST): ``pass`` (default,
  each axis within a few % of its factory trim) or ``fail`` (accelerometer Y 35 % above,
  gyroscope Z 45 % below it: the part fails, ±14 % is allowed).
- ``cube=C`` (a whole number, 0 … 2³²−1) and ``slot=K`` (0 … 7, default 0): the board sits at
  place K of virtual cube C, with the other boards given the same C (:mod:`host.bench.cube`):
  one operator holds them, C alone draws the hand (the n-th hint's motion from C and n, or
  from C and N for a hint given ``seq=N``: a sitting's own hint number), so
  boards given the same hints make the same motion, each from its own ``now`` at the hint; the
  slot gives the board's own lever arm (the slot's offset from the cube's centre, replacing the
  unit's) and its mounting (a rotation of a few mrad), both in ``port.truth``. The unit (its
  sensor's errors) and its noise still come from ``seed``. Without ``cube`` the bench is the
  board's own, as it always was.
- ``operator_fault`` (as on ``emu://``; ``fault=`` is its older spelling here) and ``fault``:
  the operator or the cable misbehaves on purpose. ``wrong_face@K``: the K-th
  ``place`` hint (default 1st) puts the next axis up (x→y→z→x, same side);
  ``incomplete_turn@K``: the K-th ``turn`` stops at 0.8 of the turns asked;
  ``too_fast@K``: the K-th ``turn`` peaks at 320 °/s (gyro saturates at ±250 °/s);
  ``pull_cable@S``: S simulated seconds after opening (default 5) ``read``/``write`` raise
  ``serial.SerialException("device disconnected")``; closing and re-opening works (once per
  port object: the re-opened board is powered up afresh and stays connected).

A thin adapter: on the wire it is the virtual firmware (:class:`host.bench.firmware.
VirtualFirmware`: HELLO, samples, STATUS, the answers to commands — byte in, byte out). This
module only paces it (``speed``), delivers its bytes through the pyserial API, resets it when
the port opens (the host's DTR) and pulls the cable.

Operator API (the calibration program tells the bench what it asks the human)::

    hint = getattr(port, "operator_hint", None)   # a real board has none: a human does it
    if hint:
        hint("place", name="x_up")                # or up=[0, 0.7071, 0.7071]
        hint("turn", axis="x", direction="ccw", turns=2, window_s=12)

Call ``place`` before the start beep: the cube is there from the next sample on. Call ``turn``
at the start beep: the operator puts the cube ``axis`` up (if it is not), starts turning about
0.8–1.3 s later and stops 0.8–1.5 s before ``window_s`` ends (default 7/12/15 s for 1/2/3
turns). Other actions are recorded and ignored. With ``operator=manual`` hints are only
recorded (``port.hints``); drive the cube yourself with ``port.set_motion(...)``.
``operator_hint`` returns what the operator did (dict: ``up``, ``fault``, ``start_s``...).

For tests: ``port.truth`` (:class:`host.bench.truth.SensorTruth`), ``port.sim`` (the running
:class:`host.bench.sim.Simulator`), ``port.sim_time`` (simulated s since the last reset),
``port.host_time_of(t_s)`` (the host's monotonic time of simulated time ``t_s``).

Boards of one cube (``cube=C``) in host time: each board takes a hint at its own ``now``, the
simulated time its wall clock has reached at the call, and schedules the hint's motion from
there; the same hint number draws the same motion on every board. The boards' motions then
agree in host time to within the time between the calls that gave them the hint (the sitting's
dialogue calls them one after another: well under a millisecond each on an idle machine), on
no common clock beyond the host's. At ``speed=max`` a board's time runs as it is read, on no
host clock: the motions agree from each board's ``now`` at the hint, in its device time.
"""

from __future__ import annotations

import threading
import time
import urllib.parse as urlparse
from typing import TYPE_CHECKING, Any

import numpy as np
from serial.serialutil import PortNotOpenError, SerialBase, SerialException, Timeout

from host.bench.firmware import RESET_EXTERNAL, RESET_POWER_ON, SelfTestPart, VirtualFirmware
from host.bench.operator import INCOMPLETE_FRACTION, TOO_FAST_PEAK_DPS, CubeOperator
from host.bench.options import (
    CABLE_FAULT,
    CLOCK_PPM_MAX,
    KEYS,
    SAMPLE_CLOCK_MAX,
    bounded,
    parse_sim_options,
)
from host.bench.physics import Environment, Motion, static_motion
from host.bench.sim import Simulator, resting_pose
from host.bench.truth import SensorTruth
from host.errors import BadURLError
from host.wire.sensor import DEFAULT_PRODUCT_ID

__all__ = ["INCOMPLETE_FRACTION", "TOO_FAST_PEAK_DPS", "Serial"]
if TYPE_CHECKING:
    from typing_extensions import Buffer

#: ``speed=max``: samples simulated at once when a reader asks what is waiting (one at a
#: time, the simulator's per-call overhead dominated a session: 3600 calls for 6000 samples)
MAX_SPEED_CHUNK = 10
#: bytes of one IMU_SAMPLE frame on the wire
_SAMPLE_BYTES = 27


class SimURLError(SerialException, BadURLError):
    """A bad ``sim://`` URL: a SerialException (what pyserial's callers expect) that
    :func:`host.board.link.open_port` tells apart by its type."""


def _usage(msg: str) -> SerialException:
    return SimURLError(f"sim:// URL: {msg} (see host/transports/protocol_sim.py)")


class Serial(SerialBase):
    """The virtual board as a pyserial port (``serial.serial_for_url("sim://...")``)."""

    #: the chip's PRODUCT_ID (``revision=``)
    product_id: int = DEFAULT_PRODUCT_ID
    #: the part fails its self-test (``self_test=fail``)
    self_test_fail: bool = False

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self._lock = threading.RLock()
        self.hints: list[tuple[float, str, dict[str, Any]]] = []
        self.truth: SensorTruth | None = None
        #: the board's firmware since the last reset (None before the first open)
        self.firmware: VirtualFirmware | None = None
        self._opened_once = False
        self._pulled_done = False
        self._pulled = False
        self._pose: Motion = static_motion("z_up")
        self._power_s = 0.0
        super().__init__(*args, **kwargs)

    @property
    def sim(self) -> Simulator | None:
        """The running simulated sensor (None before the first open)."""
        return self.firmware.sim if self.firmware is not None else None

    @property
    def _t_gen(self) -> float:
        return self.firmware.t_s if self.firmware is not None else 0.0

    @property
    def _out(self) -> bytearray:
        assert self.firmware is not None
        return self.firmware.output

    # ---- URL ---------------------------------------------------------------------------
    def from_url(self, url: str) -> None:
        """Parse the options of a ``sim://`` URL (see the module docstring)."""
        parts = urlparse.urlsplit(url)
        if parts.scheme.lower() != "sim":
            raise _usage(f"expected sim://..., got {url!r}")
        opts = urlparse.parse_qs(parts.query, keep_blank_values=True)
        known = {*KEYS, "fault", "clock_ppm", "sample_clock"}
        unknown = sorted(set(opts) - known)
        if unknown:
            raise _usage(f"unknown option(s) {', '.join(unknown)}")

        def one(key: str, default: str) -> str:
            return opts.get(key, [default])[-1]

        try:
            o = parse_sim_options(opts, speed_default="realtime", fault_is_operator=True)
            self.seed = o.seed
            self.product_id = o.product_id
            self.self_test_fail = o.self_test_fail
            self.speed: float | None = o.speed
            self.operator = o.operator
            self.faults: dict[str, float] = dict(o.operator_faults)
            if o.cable_pull_s is not None:
                self.faults[CABLE_FAULT] = o.cable_pull_s
            drawn = o.draw()
            truth, env = drawn.truth, drawn.environment
            self._noise_ss, self._op_ss = drawn.noise_ss, drawn.operator_ss
            self._cube_ss = drawn.cube_ss
            if "clock_ppm" in opts:
                ppm = bounded("clock_ppm", one("clock_ppm", "0"), -CLOCK_PPM_MAX, CLOCK_PPM_MAX)
                env = _replace(env, timer_ppm=ppm)
            if "sample_clock" in opts:
                rel = one("sample_clock", "0")
                err = bounded("sample_clock", rel, -SAMPLE_CLOCK_MAX, SAMPLE_CLOCK_MAX)
                env = _replace(env, sample_clock_error=err)
            self.environment = env
            self.bench = drawn.bench
        except ValueError as exc:
            raise _usage(str(exc)) from exc
        self.truth = truth
        self._operator = CubeOperator(
            np.random.default_rng(self._op_ss), self.bench, self.faults, self._cube_ss
        )

    # ---- open / close ------------------------------------------------------------------
    def open(self) -> None:
        """Open = the board resets (HELLO, then streaming)."""
        if self.is_open:
            raise SerialException("Port is already open.")
        if self.port is None:
            raise SerialException("Port must be configured before it can be used.")
        with self._lock:
            if not self._opened_once:
                self.from_url(self.port)
            self._reconfigure_port()
            self.is_open = True
            self._reset_board(power_cycle=not self._opened_once or self._pulled)
            self._opened_once = True

    def close(self) -> None:
        with self._lock:
            if self.is_open and self.sim is not None and not self._pulled:
                self._power_s = self.sim.power_on_s + self._t_gen
            self.is_open = False

    def _reconfigure_port(self) -> None:
        baud = self.baudrate
        if not isinstance(baud, int) or not 0 < baud < 2**32:
            raise ValueError(f"invalid baudrate: {baud!r}")

    def _reset_board(self, power_cycle: bool) -> None:
        if power_cycle:
            self._power_s = 0.0
        self._resets = getattr(self, "_resets", -1) + 1
        assert self.truth is not None
        seed = np.random.SeedSequence(
            entropy=self._noise_ss.entropy, spawn_key=(*self._noise_ss.spawn_key, self._resets)
        )
        if self.sim is not None:  # the cube stays where it is
            self._pose = resting_pose(self.sim, self._t_gen)
        self.firmware = VirtualFirmware(
            self.truth,
            self.bench,
            self.environment,
            seed,
            self._power_s,
            self._pose,
            RESET_POWER_ON if power_cycle else RESET_EXTERNAL,
            self.product_id,
            SelfTestPart(self.self_test_fail),
        )
        self._pulled = False
        self._pull_at = (
            self.faults["pull_cable"]
            if "pull_cable" in self.faults and not self._pulled_done
            else None
        )
        self._wall0 = time.monotonic()

    # ---- device side -------------------------------------------------------------------
    @property
    def sim_time(self) -> float:
        """Simulated seconds since the last reset up to which output has been produced."""
        return self._t_gen

    def host_time_of(self, t_s: float) -> float | None:
        """The host's ``time.monotonic()`` (s) at which this board reaches simulated time
        ``t_s`` (s since the last reset) at ``speed=realtime`` or ``N``; None at ``speed=max``
        (its time runs as the host reads, on no host clock)."""
        return None if self.speed is None else self._wall0 + t_s / self.speed

    def _now_target(self) -> float:
        """Simulated time the wall clock has reached (realtime / N× speed)."""
        assert self.speed is not None
        return (time.monotonic() - self._wall0) * self.speed

    def _advance(self, t_target: float) -> None:
        """Run the firmware up to simulated time ``t_target`` (or until the cable goes)."""
        assert self.firmware is not None
        if self._pulled:
            return
        if self._pull_at is not None and t_target >= self._pull_at:
            t_target = self._pull_at
        self.firmware.run_until(t_target)
        if self._pull_at is not None and self._t_gen >= self._pull_at:
            self._pulled = True
            self._pulled_done = True
            self._out.clear()

    def _pump(self, want: int = 0) -> None:
        """Bring the output up to date: to the wall clock, or (max speed) until ``want``
        bytes are waiting (at most the simulated time those bytes take, or 2 s)."""
        if self.speed is not None:
            self._advance(self._now_target())
            return
        assert self.sim is not None
        # enough time for the bytes asked (27 per sample), at least 2 s (STATUS-only output)
        limit = self._t_gen + max(2.0, 1.5 * want / 27.0 * self.sim.period_s + 1.0)
        while len(self._out) < want and self._t_gen < limit and not self._pulled:
            # just enough samples for the missing bytes (27 bytes per IMU_SAMPLE frame)
            frames = (want - len(self._out)) / 27.0
            step = min(0.1, max(1.0, frames) * self.sim.period_s)
            self._advance(min(limit, max(self._t_gen + step, self.sim.t_next + 1e-9)))

    def _check_connected(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()
        if self._pulled:
            raise SerialException("device disconnected")

    # ---- pyserial API ------------------------------------------------------------------
    @property
    def in_waiting(self) -> int:
        """Bytes ready to read (at ``speed=max``: at least :data:`MAX_SPEED_CHUNK` frames'
        worth, so that a reader asking before each read does not simulate one sample per
        call)."""
        with self._lock:
            self._check_connected()
            self._pump(1 if self.speed is not None else MAX_SPEED_CHUNK * _SAMPLE_BYTES)
            self._check_connected()
            return len(self._out)

    def read(self, size: int = 1) -> bytes:
        """Read up to ``size`` bytes; blocks until ``size`` or the timeout like a real port."""
        timeout = Timeout(self.timeout)  # type: ignore[arg-type]  # None: no limit (the stub omits it)
        while True:
            with self._lock:
                self._check_connected()
                self._pump(size)
                self._check_connected()
                if len(self._out) >= size or self.speed is None:
                    n = min(size, len(self._out))
                    data = bytes(self._out[:n])
                    del self._out[:n]
                    return data
                missing = size - len(self._out)
            if timeout.expired():
                with self._lock:
                    data = bytes(self._out[:size])
                    del self._out[: len(data)]
                    return data
            # about the time the missing bytes take at 50 Hz × 27 bytes, sped up
            wait = min(0.05, max(0.001, missing / (1350.0 * self.speed)))
            left = timeout.time_left()
            if left is not None:
                wait = min(wait, left)
            time.sleep(wait)

    def write(self, data: Buffer, /) -> int:
        """Commands to the board; answered at the current simulated time."""
        with self._lock:
            self._check_connected()
            if self.speed is not None:
                self._advance(self._now_target())
                self._check_connected()
            assert self.firmware is not None
            self.firmware.receive(bytes(data))
            return len(memoryview(data))

    def reset_input_buffer(self) -> None:
        with self._lock:
            self._check_connected()
            if self.speed is not None:
                self._advance(self._now_target())
            self._out.clear()

    def reset_output_buffer(self) -> None:
        self._check_connected()

    @property
    def out_waiting(self) -> int:
        return 0

    def cancel_read(self) -> None:
        pass

    def cancel_write(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    def _update_break_state(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        return True

    @property
    def dsr(self) -> bool:
        return True

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return True

    # ---- the operator ------------------------------------------------------------------
    def set_motion(self, motion: Motion, t_from_s: float | None = None) -> None:
        """Move the cube yourself (manual operator): ``motion`` from ``t_from_s`` simulated s
        since the reset (default: now)."""
        with self._lock:
            assert self.sim is not None
            if self.speed is not None:
                self._advance(self._now_target())
            t = self._t_gen if t_from_s is None else max(t_from_s, self._t_gen)
            self.sim.set_motion(motion, t)

    def operator_hint(self, action: str, **kw: Any) -> dict[str, Any]:
        """What the calibration program asks the operator (see the module docstring)."""
        with self._lock:
            if self.is_open and self.speed is not None and not self._pulled:
                self._advance(self._now_target())
            now = self._t_gen
            self.hints.append((now, action, dict(kw)))
            if self.operator != "auto" or self.sim is None:
                return {"action": action, "done": False}
            return self._operator.hint(self.sim, now, action, **kw)


def _replace(env: Environment, **kw: Any) -> Environment:
    import dataclasses

    return dataclasses.replace(env, **kw)
