"""``emu://`` — the emulated APM 2.6 (real firmware on simavr, MPU-6000 model) as a pyserial port.

URL grammar (all options optional, ``&``-separated)::

    emu://[?elf=PATH][&seconds=N][&realtime=0|1][&stimulus=PATH][&fault=absent|stuck-miso|no-drdy]
          [&fault_at=S][&noise_accel=SIGMA][&noise_gyro=SIGMA][&seed=S][&clock_ppm=PPM]
          [&reglog=PATH][&samplelog=PATH][&workdir=DIR][&boot=0|1][&flash=PATH]
          [&speed=max|N|realtime][&truth=random|ideal][&effects=NAME,NAME...]
          [&operator=auto|manual][&latitude=DEG][&tilt=DEG][&earth_rate=0|1]
          [&operator_fault=wrong_face[@K]|incomplete_turn[@K]|too_fast[@K]]...
          [&chamber=FROM:TO:MINUTES[@START_S]][&revision=D8|C4|C5|...|0xNN]
          [&self_test=pass|fail][&cube=C[&slot=K]]

- ``elf``: firmware to run, an ``.elf`` or ``.hex`` (default: ``make -C firmware`` into
  ``firmware/build/`` first; with ``boot``/``flash``: whatever the flash holds).
- ``seconds``: simulated seconds before the board stops answering (default: until the stimulus
  ends, or until the port is closed without one).
- ``realtime``: 1 paces simulated time to the wall clock; default 0 runs as fast as the host
  reads (tens of times real time), so device time runs ahead of host time.
- ``stimulus``: where the MPU-6000 model's physical truth comes from. ``sim`` (the default):
  the project's physics simulator (below), so plain ``emu://`` is a whole virtual bench whose
  operator follows the calibration program (``python3 -m host calibrate --port emu://`` works
  as it does with ``sim://``); ``rest``: at rest, Z up, 25 °C, exactly (no noise, no sensor
  errors; the emulator's own ``noise_*`` options add white noise); a path: a stimulus file
  (``host.bench.stimulus.write_stimulus``).
- ``seed`` (default: from ``serial``, else 0): with ``stimulus=sim`` draws the unit — its truth
  and room — as in ``sim://`` (same seed, same sensor); ``noise_seed`` the noise and the
  operator (not given: fresh in every session); ``seed`` also seeds the emulator's ``noise_*``.
- ``speed`` (``stimulus=sim``): ``max`` (default) — the simulator keeps ahead of the emulator,
  which runs as fast as it can and the host reads; ``N`` — the simulator's horizon advances at
  N× the wall clock, so emulated time does too (paced in 2 ms steps: a device clock right to
  ≈ 50 ppm); ``realtime`` (or 1) — the emulator paces itself to the wall clock (as
  ``realtime=1``: a device clock right to a few ppm), the simulator keeping ahead of it.
- ``truth``, ``effects``, ``latitude``, ``tilt``, ``earth_rate``, ``operator``, ``chamber``: as in
  ``sim://`` (``host/transports/protocol_sim.py``); ``operator=manual``: hints are only
  recorded (``port.hints``), move the cube with ``port.set_motion(motion)``.
- ``cube``, ``slot``: the board sits at place K of virtual cube C, its operator's hand shared
  with the cube's other boards, as in ``sim://`` (:mod:`host.bench.cube`).
- ``operator_fault`` (may repeat): the virtual operator misbehaves on purpose, as ``sim://``'s
  operator faults: the K-th ``place`` puts the wrong face up, the K-th ``turn`` stops at 0.8 of
  the turns or peaks at 320 °/s (beyond the ±250 °/s range). (``fault`` here is a *sensor*
  fault.)
- ``fault``: sensor fault from ``fault_at`` simulated seconds on (default 0): ``absent`` (no
  answer on SPI, no data-ready), ``stuck-miso`` (every byte read is 0xFF), ``no-drdy`` (the INT
  line never rises), ``marginal-bus`` (above 1 MHz SCLK every byte read arrives one bit late:
  the firmware's burst check drops to the 1 MHz clock and sets STATUS.flags SPI_LOW_CLOCK).
- ``revision``: what the chip's PRODUCT_ID reads (``host.bench.options.parse_revision``):
  ``D8`` (default), ``C4``/``C5`` (half the accelerometer LSB/g at every AFS_SEL), ``D6`` …
  ``D10``, or a number (``0x55``); with any stimulus.
- ``self_test``: how the emulated chip answers the self-test, with any stimulus: ``pass``
  (default) or ``fail`` (accelerometer Y 35 % above its factory trim, gyroscope Z 45 % below).
- ``noise_accel`` (m/s²), ``noise_gyro`` (°/s), ``seed``: white noise added before quantisation.
- ``clock_ppm``: MPU-6000 sample clock error against the AVR crystal.
- ``reglog``, ``samplelog``: write the register-access / produced-sample CSV logs there.
- ``boot``: 1 boots like the real board: Debian's stk500v2 bootloader (arduino-core-avr) at
  0x3E000 runs after every reset, including the DTR reset of each open, waits ≈ 0.8 s (real time)
  for avrdude, then starts the application. Default 0 (the application starts at once).
- ``flash``: the chip's flash persisted in this file (raw 256 KiB image; implies ``boot=1``):
  loaded at start if it exists (else an empty chip, or ``elf`` programmed into it), written back
  when avrdude has programmed it and at exit — flash once (``python3 -m host flash --port
  'emu://?flash=PATH'``), then open ``emu://?flash=PATH`` as often as you like.

Opening the port starts the emulator and opens its pseudo-terminal (the open is the DTR reset:
the AVR starts from reset); closing stops it. After ``close()``, ``port.emulator_summary`` holds
the emulator's summary (speed, SPI violations, bus conflicts, samples, CPU cycles per sample);
while open, ``port.board`` is the :class:`host.bench.emulator.EmulatedBoard`.

Simulator stimulus (``stimulus=sim``): a :class:`host.bench.sim.Simulator` at 1 kHz (the chip's
internal rate; the emulated chip's samples each take the last record before them) feeds the
emulator's stimulus pipe through :class:`host.bench.stimulus.SimStimulus`, at most ≈ 80 ms of
emulated time ahead; the emulator waits when the records run dry, so emulated time is gated by
what the host has fed. ``port.operator_hint("place", name=...)`` / ``("turn", axis=, direction=,
turns=, window_s=)`` act as in ``sim://`` (:class:`host.bench.operator.CubeOperator`): the motion
starts at the fed horizon, and the call returns once the emulator has got 30 ms past it — every
sample sent before the change is then in the port's input, so a measurement that drops what the
port holds at its start beep sees only the new pose. The emulated time then stands still 35 ms
past the change until the host next writes to the port or reads from it: in ``--yes`` mode the
next I/O is the start beep's PING, so the beep, and with it the measurement window, lands at the
same emulated instant after the hint however slow or loaded the host is (a turn starts 0.8–1.3 s
after the hint: never cut by the window's start); a program that reads the port while it waits
for a human operator lets the time go on as a real board's would. ``port.truth`` is the
:class:`host.bench.truth.SensorTruth`, ``port.sim`` the running simulator, ``port.sim_time`` the
emulated time (s, a lower bound). The clocks are the emulator's: the AVR crystal is exact, the
MPU sample clock is off by ``clock_ppm``. Re-opening the port (after ``close()``, or when the
emulator died) starts a new emulator with the same sensor, the cube where it was.

Needs simavr, libsimavr-dev, gcc-avr and avr-libc; without them ``open()`` raises
:class:`host.errors.UserError` saying so.
"""

from __future__ import annotations

import contextlib
import dataclasses
import urllib.parse as urlparse
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

import numpy as np
from serial.serialposix import Serial as PosixSerial
from serial.serialutil import SerialException

from host.bench.emulator import FAULTS, EmulatedBoard
from host.bench.options import (
    KEYS,
    SAMPLE_CLOCK_MAX,
    OptionError,
    SimOptions,
    bounded,
    parse_revision,
    parse_self_test,
)
from host.bench.options import parse_sim_options as parse_bench_options
from host.bench.stimulus import STIM_RECORD_HZ, SimStimulus
from host.errors import UserError
from host.transports.flashing import FlashPort

if TYPE_CHECKING:
    from host.bench.operator import CubeOperator
    from host.bench.physics import Bench, Environment, Motion
    from host.bench.sim import Simulator
    from host.bench.truth import SensorTruth

_FLOAT = ("seconds", "fault_at", "noise_accel", "noise_gyro", "clock_ppm")
_PATH = ("elf", "stimulus", "reglog", "samplelog", "workdir", "flash")
#: options of the simulator stimulus (parse_sim_options), not of the EmulatedBoard
_SIM_KEYS = tuple(k for k in KEYS if k not in ("seed", "revision", "self_test"))
#: after an operator hint, wait until the emulator is this far past the change, s (every
#: sample taken before it has then been sent to the port)
HINT_SYNC_S = 0.03
#: after an operator hint the emulated time stops this far past the change, s, until the host
#: next writes to or reads from the port (the start beep's PING): where the beep lands in
#: emulated time then does not depend on how fast the host is (HINT_SYNC_S plus one stimulus
#: record, 1 ms, and a little room)
HINT_HOLD_S = HINT_SYNC_S + 0.005


def check_firmware_file(path: str) -> str:
    """``elf=PATH``: an existing ELF or Intel HEX file (ValueError saying what it is not)."""
    try:
        with open(path, "rb") as f:
            head = f.read(4)
    except OSError as exc:
        raise ValueError(f"cannot read the firmware file ({exc.strerror})") from None
    if head != b"\x7fELF" and not head.startswith(b":"):
        raise ValueError(
            "not an ELF or Intel HEX file; give the firmware's .elf or .hex "
            "(make -C firmware builds firmware/build/imu_bench.elf)"
        )
    return path


def parse_url(url: str) -> dict[str, Any]:
    """``emu://?...`` -> keyword arguments for :class:`EmulatedBoard` (ValueError if bad)."""
    parts = urlparse.urlsplit(url)
    if parts.scheme != "emu":
        raise ValueError(f"expected an emu:// URL, not {url!r}")
    if parts.netloc or parts.path not in ("", "/"):
        raise ValueError(f"emu:// takes only ?options, not {parts.netloc + parts.path!r}")
    kw: dict[str, Any] = {}
    for key, values in urlparse.parse_qs(parts.query, keep_blank_values=True).items():
        value = values[-1]
        try:
            if key == "clock_ppm":  # the MPU-6000's sample clock: its oscillator is within ±5 %
                kw[key] = bounded(key, value, -SAMPLE_CLOCK_MAX * 1e6, SAMPLE_CLOCK_MAX * 1e6)
            elif key in _FLOAT:
                kw[key] = bounded(key, value, 0.0, 1e6)
            elif key == "elf":
                kw[key] = check_firmware_file(value)
            elif key in _PATH:
                kw[key] = value
            elif key in _SIM_KEYS:
                continue  # parse_sim_options
            elif key in ("realtime", "boot"):
                kw[key] = value.lower() in ("1", "true", "yes", "")
            elif key == "seed":
                kw[key] = int(value, 0)
            elif key == "revision":  # the chip's, whatever the stimulus
                kw["product_id"] = parse_revision(value)
            elif key == "self_test":  # the chip's too
                kw["self_test"] = "fail" if parse_self_test(value) else "pass"
            elif key == "fault":
                if value not in FAULTS:
                    raise ValueError(f"fault must be one of {', '.join(FAULTS)}")
                kw[key] = value
            else:
                raise ValueError("unknown option")
        except ValueError as exc:
            raise ValueError(f"emu:// option {key}={value!r}: {exc}") from None
    return kw


def parse_sim_options(url: str) -> SimOptions | None:
    """The simulator options of an ``emu://`` URL (:func:`host.bench.options.parse_sim_options`,
    as ``sim://``'s), or None when the stimulus is ``rest`` or a file (ValueError if bad)."""
    opts = urlparse.parse_qs(urlparse.urlsplit(url).query, keep_blank_values=True)
    if opts.get("stimulus", ["sim"])[-1] != "sim":
        return None
    try:
        return parse_bench_options(opts, speed_default="max", fault_is_operator=False)
    except OptionError as exc:
        value = opts.get(exc.key, [""])[-1]
        raise ValueError(f"emu:// option {exc.key}={value!r}: {exc}") from None


def truth_for_url(url: str) -> SensorTruth | None:
    """The sensor truth the simulator of an ``emu://`` URL has (what ``port.truth`` is once the
    port is open; None when the stimulus is ``rest`` or a file) — without starting anything."""
    o = parse_sim_options(url)
    return _Bench(o).truth if o is not None else None


@contextlib.contextmanager
def serve_flash(url: str) -> Iterator[FlashPort]:
    """``emu://?flash=PATH[&workdir=DIR]`` for a flasher (:mod:`host.transports.flashing`): an
    emulated board booting into its bootloader with the chip's flash kept in PATH; the device
    is its pseudo-terminal while the ``with`` block runs, then the emulator stops (``summary``:
    its run) and PATH holds what was flashed. Only the chip matters for flashing: no stimulus,
    logs or faults from the URL. UserError for a bad URL or no flash file."""
    try:
        kw = parse_url(url)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    if not kw.get("flash"):
        raise UserError(
            "flashing an emulated board needs a flash file to keep what is flashed: "
            "--port 'emu://?flash=PATH'"
        )
    board = EmulatedBoard(flash=kw["flash"], boot=True, workdir=kw.get("workdir"))
    board.start()
    port = FlashPort("")
    try:
        assert board.port is not None
        port.device = board.port
        yield port
    finally:
        port.summary = board.stop()
        board.cleanup()


class _Bench:
    """What stays the same across emulator restarts: the sensor, the room, the bench, the
    operator, and where the cube is."""

    def __init__(self, o: SimOptions) -> None:
        from host.bench.operator import CubeOperator
        from host.bench.physics import static_motion

        drawn = o.draw()
        self.noise_ss = drawn.noise_ss
        op_ss = drawn.operator_ss
        self.truth: SensorTruth = drawn.truth
        # the clocks are the emulator's (exact AVR crystal, MPU off by clock_ppm)
        self.environment: Environment = dataclasses.replace(
            drawn.environment, timer_ppm=0.0, sample_clock_error=0.0
        )
        self.bench: Bench = drawn.bench
        self.operator: CubeOperator = CubeOperator(
            np.random.default_rng(op_ss), self.bench, dict(o.operator_faults), drawn.cube_ss
        )
        self.pose: Motion = static_motion("z_up")
        self.power_s = 0.0
        self.starts = 0

    def simulator(self) -> Simulator:
        """A fresh simulator for a (re)started emulator: new noise, same sensor and pose."""
        from host.bench.sim import Simulator

        ss = self.noise_ss
        seed = np.random.SeedSequence(ss.entropy, spawn_key=(*ss.spawn_key, self.starts))
        self.starts += 1
        sim = Simulator(
            self.truth, self.bench, self.environment, seed, STIM_RECORD_HZ, self.power_s
        )
        sim.set_motion(self.pose, 0.0)
        return sim


class Serial(PosixSerial):
    """pyserial port whose ``open()`` starts an emulated board and opens its pty (and, with
    the simulator stimulus, the simulator that feeds it)."""

    board: EmulatedBoard | None = None
    emulator_summary: dict[str, Any] | None = None

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.stimulus: SimStimulus | None = None
        self.hints: list[tuple[float, str, dict[str, Any]]] = []
        self.truth: SensorTruth | None = None
        self._bench: _Bench | None = None
        self._sim_opts: SimOptions | None = None
        self._held = bytearray()
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        if self.port is None:
            raise SerialException("Port must be configured before it can be used.")
        if self.is_open:
            raise SerialException("Port is already open.")
        kwargs = parse_url(self.port)
        sim_opts = parse_sim_options(self.port)
        feed_speed = None
        if sim_opts is not None:
            kwargs["stimulus"] = "pipe"
            if sim_opts.speed == 1.0:  # the emulator's own pacing: exact to a few ppm
                kwargs["realtime"] = True
            else:
                feed_speed = sim_opts.speed
            if self._bench is None or sim_opts != self._sim_opts:
                self._bench, self._sim_opts = _Bench(sim_opts), sim_opts
                self.truth = self._bench.truth
        elif kwargs.get("stimulus") == "rest":
            del kwargs["stimulus"]
        board = EmulatedBoard(**kwargs)
        board.start()  # UserError (missing simavr, build failure) propagates as is
        stim = None
        if sim_opts is not None:
            assert self._bench is not None
            stim = SimStimulus(board, self._bench.simulator(), feed_speed).start()
        url = self.portstr
        self.portstr = board.port
        try:
            super().open()
        except BaseException:
            if stim is not None:
                stim.request_stop()
            board.stop()
            if stim is not None:
                stim.stop()
            raise
        finally:
            self.portstr = url
        self._held.clear()
        if stim is not None:
            stim.restart_clock()  # the emulated CPU starts now
        self.board = board
        self.stimulus = stim
        self.emulator_summary = None

    def close(self) -> None:
        stim, self.stimulus = self.stimulus, None
        if stim is not None:
            stim.request_stop()
            with stim.lock:
                if self._bench is not None:  # the cube stays where it is
                    from host.bench.sim import resting_pose

                    self._bench.pose = resting_pose(stim.sim, stim.horizon_s)
                    alive = self.board is not None and self.board.running
                    # a vanished emulator is a power cycle; a close keeps the chip warm
                    self._bench.power_s = stim.sim.power_on_s + stim.horizon_s if alive else 0.0
        super().close()
        self._held.clear()
        board, self.board = self.board, None
        if board is not None:
            self.emulator_summary = board.stop()
        if stim is not None:
            stim.stop()

    def from_url(self, url: str) -> str:
        parse_url(url)
        parse_sim_options(url)
        return url

    # ---- the simulator bench -------------------------------------------------------------
    @property
    def sim(self) -> Simulator | None:
        """The simulator feeding the running emulator (None without one)."""
        return self.stimulus.sim if self.stimulus is not None else None

    @property
    def sim_time(self) -> float:
        """Emulated seconds since the emulator started (a lower bound; 0 without a simulator)."""
        return self.stimulus.emulated_s() if self.stimulus is not None else 0.0

    @property
    def operator_hint(self) -> Callable[..., dict[str, Any]]:
        """What the calibration program asks the operator (``place`` / ``turn``, as in
        ``sim://``): the cube moves at the fed horizon; the call returns once the emulator is
        :data:`HINT_SYNC_S` past it, with what the operator did (dict). Only with the
        simulator stimulus: with ``stimulus=rest`` or a file nobody moves the cube, and the
        attribute is absent (``hasattr(port, "operator_hint")`` is False, as on a real board)."""
        if parse_sim_options(self.port or "emu://") is None:
            raise AttributeError("operator_hint: emu:// without the simulator has no operator")
        return self._operator_hint

    def _operator_hint(self, action: str, **kw: Any) -> dict[str, Any]:
        stim = self.stimulus
        if stim is None or self._bench is None:
            self.hints.append((0.0, action, dict(kw)))
            return {"action": action, "done": False}
        with stim.lock:
            now = stim.horizon_s
            self.hints.append((now, action, dict(kw)))
            if self._sim_opts is None or self._sim_opts.operator != "auto":
                return {"action": action, "done": False}
            result = self._bench.operator.hint(stim.sim, now, action, **kw)
            if result.get("done"):
                # the operator acts on the program's start beep: no emulated time passes
                # until the host sends it (write), however long the host takes
                stim.hold_at(now + HINT_HOLD_S)
        if result.get("done"):
            stim.wait_emulated(now + HINT_SYNC_S, idle=self._hold_input)
        return result

    def set_motion(self, motion: Motion, t_from_s: float | None = None) -> None:
        """Move the cube yourself (``operator=manual``): ``motion`` from ``t_from_s`` emulated
        s (default and at the earliest: the fed horizon, "now")."""
        stim = self.stimulus
        if stim is None:
            raise SerialException("set_motion needs the simulator stimulus (stimulus=sim)")
        with stim.lock:
            t = stim.horizon_s if t_from_s is None else max(t_from_s, stim.horizon_s)
            stim.sim.set_motion(motion, t)
        stim.wait_emulated(t + HINT_SYNC_S, idle=self._hold_input)

    def write(self, data: Any) -> int | None:
        """Write to the board; the first write after an operator hint (the start beep's
        PING) lets the emulated time go on — after the bytes are in the pty, so that the
        board reads them at the held instant."""
        n = super().write(data)
        self._release_hint_hold()
        return n

    def _release_hint_hold(self) -> None:
        """The host acts again after an operator hint: the emulated time goes on."""
        stim = self.stimulus
        if stim is not None and stim.holding:
            stim.release()

    # ---- input held while waiting for the emulator ---------------------------------------
    def _hold_input(self) -> None:
        """Read what the pty holds into a buffer that read() serves first (the emulator stops
        when the pty is full, and it must get past a hint)."""
        try:
            n = super().in_waiting
            if n:
                self._held += super().read(n)
        except (OSError, SerialException):
            pass  # the next read reports it

    @property
    def in_waiting(self) -> int:
        return len(self._held) + super().in_waiting

    def read(self, size: int = 1) -> bytes:
        """Read from the board (what :meth:`_hold_input` kept first). A read after an operator
        hint lets the emulated time go on: the host reads while it waits for a person."""
        self._release_hint_hold()
        if not self._held:
            return super().read(size)
        n = min(size, len(self._held))
        data = bytes(self._held[:n])
        del self._held[:n]
        if n < size:
            more = super().in_waiting
            if more:
                data += super().read(min(more, size - n))
        return data

    def reset_input_buffer(self) -> None:
        self._held.clear()
        super().reset_input_buffer()
