"""The bench simulator: a virtual MPU-6000 on the cube fixture, deterministic from a seed.

Layers (all numpy):

- :mod:`host.bench.truth` — :class:`SensorTruth` (every error term, report names) and the model.
- :mod:`host.bench.physics` — attitude of the cube, hand turns, gravity/Earth rate, room, clocks.
- this module — :class:`Simulator` (a running sensor: samples -> counts, as the board sends
  them), the hand-turn and rate-table motions, motion schedules (:func:`simulate_scenario`),
  frame streams (:func:`imu_frames`) and the truth time series for the emulated board
  (:func:`truth_series`).
- :mod:`host.bench.operator` — the virtual operator who carries out the program's hints.
- :mod:`host.bench.plan` — :class:`~host.bench.plan.Plan` and
  :func:`~host.bench.plan.simulate_session` (record objects exactly as the calibration program
  writes them, fast path for tests), :func:`~host.bench.plan.write_session`.

Output chain per sample: true specific force / rate (body frame) -> error model -> quantise to
the LSB via :mod:`host.wire.sensor` (±2 g, ±250 °/s) with saturation at full scale -> int16
counts; records hold the counts converted back exactly as the host converts them.

Timing: the sensor samples at ``rate_hz·(1 + Environment.sample_clock_error)`` true Hz; the
device time stamp is the MCU µs timer (``Environment.device_us``). Times ``t_s`` are true
seconds since the board's reset (device clock zero); the chip's warm-up and drift run on
``t_s + Simulator.power_on_s`` (a reset does not cool the chip).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from host.bench.physics import (
    Bench,
    ConstantRateMotion,
    Environment,
    Motion,
    TurnMotion,
    TurnProfile,
    Wobble,
    body_inputs,
    static_motion,
    up_vector,
)
from host.bench.truth import SensorTruth, gauss_markov, sensor_output
from host.model.geometry import pose_from_up
from host.wire import sensor
from host.wire.protocol_gen import ENUMS

#: flag bit of IMU_SAMPLE (spec enum sample_flags)
CONFIG_CHANGED = ENUMS["sample_flags"]["CONFIG_CHANGED"]
SeedLike = int | np.random.SeedSequence


# --------------------------------------------------------------------------- samples
@dataclass(frozen=True)
class SampleBlock:
    """Consecutive samples as the board sends them, with their true time.

    ``t_s`` (N,) true s since power-on; ``t_us`` (N,) int64 device timer (not wrapped);
    ``counts`` (N, 7) int16 ax, ay, az, temp, gx, gy, gz; ``flags`` (N,) uint8.
    """

    t_s: np.ndarray
    t_us: np.ndarray
    counts: np.ndarray
    flags: np.ndarray

    def __len__(self) -> int:
        return int(self.t_s.shape[0])

    @property
    def accel(self) -> np.ndarray:
        """(N, 3) m/s², converted from counts as the host does."""
        return sensor.accel_mps2(self.counts[:, 0:3])

    @property
    def gyro(self) -> np.ndarray:
        """(N, 3) °/s, converted from counts as the host does."""
        return sensor.gyro_dps(self.counts[:, 4:7])

    @property
    def temp(self) -> np.ndarray:
        """(N,) °C from the TEMP_OUT counts."""
        return sensor.temp_c(self.counts[:, 3])

    @staticmethod
    def concat(blocks: Sequence[SampleBlock]) -> SampleBlock:
        """Join blocks in order."""
        if not blocks:
            return SampleBlock(
                np.zeros(0),
                np.zeros(0, np.int64),
                np.zeros((0, 7), np.int16),
                np.zeros(0, np.uint8),
            )
        return SampleBlock(
            np.concatenate([b.t_s for b in blocks]),
            np.concatenate([b.t_us for b in blocks]),
            np.concatenate([b.counts for b in blocks]),
            np.concatenate([b.flags for b in blocks]),
        )


def quantise(
    accel: np.ndarray, gyro: np.ndarray, temp_c: np.ndarray, product_id: int | None = None
) -> np.ndarray:
    """Physical outputs -> (N, 7) int16 counts (rounded to the LSB, saturated at full scale),
    ±2 g and ±250 °/s as the firmware configures the chip (AFS_SEL 0 counts half the LSB/g on
    revisions C4/C5: ``product_id``, :func:`host.wire.sensor.accel_lsb_per_g`)."""
    n = accel.shape[0]
    out = np.empty((n, 7), dtype=np.int16)
    out[:, 0:3] = sensor.accel_counts(accel, 0, product_id)
    out[:, 3] = sensor.temp_counts(temp_c)
    out[:, 4:7] = sensor.gyro_counts(gyro, 0)
    return out


class Simulator:
    """A powered sensor on the bench, producing samples in time order.

    The cube's motion is a schedule of :class:`~host.bench.physics.Motion` objects, each in
    force from its start time (:meth:`set_motion`). :meth:`run_until` returns every sample
    before a time, :meth:`skip_until` advances without output (the bias random process is
    propagated exactly over the gap). Same seed and same calls -> same output.
    """

    def __init__(
        self,
        truth: SensorTruth,
        bench: Bench | None = None,
        environment: Environment | None = None,
        seed: SeedLike = 0,
        rate_hz: float = 50.0,
        power_on_s: float = 0.0,
    ) -> None:
        self.truth = truth
        #: the chip's PRODUCT_ID (its revision: C4/C5 count half the accelerometer LSB/g)
        self.product_id = sensor.DEFAULT_PRODUCT_ID
        #: how long the sensor had been powered when this simulator's clock read 0, s
        #: (a board reset restarts the device clock but not the chip's warm-up)
        self.power_on_s = power_on_s
        self.bench = bench or Bench()
        self.environment = environment or Environment()
        ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        noise_ss, walk_ss, phase_ss = ss.spawn(3)
        self._noise_rng = np.random.default_rng(noise_ss)
        self._walk_rng = np.random.default_rng(walk_ss)
        self.rate_hz = rate_hz
        #: true time of the next sample, s since the reset
        self.t_next = float(np.random.default_rng(phase_ss).uniform(0.0, self.period_s))
        self._segments: list[tuple[float, Motion]] = [(-np.inf, static_motion("z_up"))]
        self._walk = np.zeros(6)
        self._walk_t = 0.0
        self._config_changed = False
        #: samples produced (including skipped ones)
        self.samples = 0

    # ---- configuration -----------------------------------------------------------------
    @property
    def period_s(self) -> float:
        """True sample period, s (nominal rate with the sample clock error)."""
        return 1.0 / (self.rate_hz * (1.0 + self.environment.sample_clock_error))

    def set_rate(self, rate_hz: float) -> None:
        """Change the output rate from the next sample on (which carries CONFIG_CHANGED)."""
        self.rate_hz = rate_hz
        self._config_changed = True

    def set_motion(self, motion: Motion, t_from_s: float | None = None) -> None:
        """Make ``motion`` the cube's motion from ``t_from_s`` (default: the next sample)."""
        t = self.t_next if t_from_s is None else float(t_from_s)
        self._segments = [(s, m) for s, m in self._segments if s < t] + [(t, motion)]

    def motion_at(self, t_s: float) -> Motion:
        """The motion in force at time ``t_s``."""
        cur = self._segments[0][1]
        for s, m in self._segments:
            if s <= t_s:
                cur = m
        return cur

    # ---- running -----------------------------------------------------------------------
    def skip_until(self, t_end_s: float) -> int:
        """Advance past every sample before ``t_end_s`` without producing them; -> count."""
        if t_end_s <= self.t_next:
            return 0
        n = int(np.ceil((t_end_s - self.t_next) / self.period_s))
        self.t_next += n * self.period_s
        self.samples += n
        return n

    def run_until(self, t_end_s: float) -> SampleBlock:
        """Every sample with true time before ``t_end_s``."""
        n = 0 if t_end_s <= self.t_next else int(np.ceil((t_end_s - self.t_next) / self.period_s))
        return self.run_samples(n)

    def run_samples(self, n: int) -> SampleBlock:
        """The next ``n`` samples."""
        dt = self.period_s
        t = self.t_next + dt * np.arange(n)
        self.t_next += n * dt
        self.samples += n
        block = self._generate(t, dt)
        return block

    def outputs_until(self, t_end_s: float) -> TruthSeries:
        """Every sample before true time ``t_end_s`` as the sensor's physical output, before
        quantisation: ``specific_force`` m/s², ``rate_dps`` °/s (body axes, errors and noise
        applied), ``temp_c`` °C. The same random stream as :meth:`run_until` (for a stimulus
        that the emulated MPU-6000 quantises itself)."""
        n = 0 if t_end_s <= self.t_next else int(np.ceil((t_end_s - self.t_next) / self.period_s))
        dt = self.period_s
        t = self.t_next + dt * np.arange(n)
        self.t_next += n * dt
        self.samples += n
        accel, gyro, temp = self._outputs(t, dt)
        self._config_changed = False
        return TruthSeries(t, accel, gyro, temp)

    def _generate(self, t: np.ndarray, dt: float) -> SampleBlock:
        n = t.shape[0]
        accel, gyro, temp = self._outputs(t, dt)
        flags = np.zeros(n, dtype=np.uint8)
        if n and self._config_changed:
            flags[0] |= CONFIG_CHANGED
            self._config_changed = False
        counts = quantise(accel, gyro, temp, self.product_id)
        return SampleBlock(t, self.environment.device_us(t), counts, flags)

    def _outputs(self, t: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Physical sensor output at the sample times ``t`` (period ``dt``): accel (N, 3)
        m/s², gyro (N, 3) °/s, temperature (N,) °C."""
        n = t.shape[0]
        truth = self.truth
        f = np.zeros((n, 3))
        w = np.zeros((n, 3))
        starts = np.array([s for s, _ in self._segments])
        idx = np.searchsorted(starts, t, side="right") - 1
        for i in np.unique(idx):
            sel = idx == i
            f[sel], w[sel] = body_inputs(
                self._segments[i][1], t[sel], self.bench, np.asarray(truth.lever_arm_m)
            )
        t_power = t + self.power_on_s
        temp = self.environment.temperature(t_power)
        sigma = np.concatenate([truth.accel_noise, truth.gyro_noise])
        disturbance = self._noise_rng.standard_normal((n, 6)) * sigma
        walk_sigma = np.concatenate([truth.accel_bias_instability, truth.gyro_bias_instability])
        if n:
            tau = truth.bias_corr_time_s
            gap = t[0] - dt - self._walk_t
            if gap > 0 and np.any(walk_sigma):
                phi = float(np.exp(-gap / tau))
                self._walk = phi * self._walk + walk_sigma * np.sqrt(
                    1 - phi * phi
                ) * self._walk_rng.standard_normal(6)
            walk = gauss_markov(self._walk_rng, self._walk, n, dt, tau, walk_sigma)
            self._walk = walk[-1]
            self._walk_t = float(t[-1])
            disturbance += walk
        accel, gyro = sensor_output(
            truth, f, w, temp, t_power, self.bench.g, disturbance[:, :3], disturbance[:, 3:]
        )
        return accel, gyro, temp


# --------------------------------------------------------------------------- motions
def turn_motion(
    rng: np.random.Generator,
    up_body: np.ndarray | str,
    t_beep_s: float,
    window_s: float,
    turns: float,
    direction: int,
    wobble_deg: float = 1.0,
    fraction: float = 1.0,
    peak_dps: float | None = None,
) -> TurnMotion:
    """A hand turn about the vertical inside the window ``[t_beep_s, t_beep_s + window_s]``.

    The operator starts ~1 s after the beep (0.8–1.3 s) and stops 0.8–1.5 s before the end;
    the angle is ``direction · fraction · turns · 360°`` (``fraction`` < 1: an incomplete
    turn). ``peak_dps``: compress the same profile in time until its peak reaches this rate
    (a too-fast turn).
    """
    up = up_vector(up_body) if isinstance(up_body, str) else np.asarray(up_body, dtype=float)
    pre = float(rng.uniform(0.8, 1.3))
    post = float(rng.uniform(0.8, 1.5))
    start = t_beep_s + pre
    duration = max(window_s - pre - post, 0.5)
    angle = direction * fraction * turns * 360.0
    profile = TurnProfile.random(rng, start, duration, angle)
    if peak_dps is not None:
        profile = profile.scaled_in_time(profile.peak_rate() / peak_dps)
    wobble = Wobble.random(rng, profile.start, profile.end, wobble_deg) if wobble_deg > 0 else None
    attitude = tuple(tuple(float(x) for x in row) for row in pose_from_up(up))
    return TurnMotion(attitude, profile=profile, wobble=wobble)


def rate_table_motion(up_body: np.ndarray | str, rate_dps: float, t0_s: float) -> Motion:
    """The cube on a rate table turning at ``rate_dps`` about its ``up_body`` axis."""
    up = up_vector(up_body) if isinstance(up_body, str) else np.asarray(up_body, dtype=float)
    attitude = tuple(tuple(float(x) for x in row) for row in pose_from_up(up))
    return ConstantRateMotion(attitude, rate_dps=rate_dps, start_s=t0_s)


# --------------------------------------------------------------------------- the cube at rest
def resting_pose(sim: Simulator, t_s: float) -> Motion:
    """The cube's attitude at ``t_s`` as a motion at rest (it stays where it is when the board
    restarts)."""
    r, _ = sim.motion_at(t_s).kinematics(np.array([t_s]))
    return Motion(tuple(tuple(float(x) for x in row) for row in r[0]))


# --------------------------------------------------------------------------- scenarios
#: a time-varying scenario: (start time s since power-on, motion in force from then), in order
Scenario = Sequence[tuple[float, Motion]]


def _scheduled(sim: Simulator, scenario: Scenario) -> None:
    for t0, motion in scenario:
        sim.set_motion(motion, t0)


def simulate_scenario(
    truth: SensorTruth,
    scenario: Scenario,
    duration_s: float,
    seed: SeedLike = 0,
    bench: Bench | None = None,
    environment: Environment | None = None,
    rate_hz: float = 50.0,
) -> SampleBlock:
    """Every sample of ``[0, duration_s)`` s since power-on for a motion schedule."""
    sim = Simulator(truth, bench, environment, seed, rate_hz)
    _scheduled(sim, scenario)
    return sim.run_until(duration_s)


def imu_frames(
    sim: Simulator, t_end_s: float, seq0: int = 0, chunk_s: float = 1.0
) -> Iterator[bytes]:
    """IMU_SAMPLE frames (wire bytes, ``chunk_s`` s of samples per chunk) for every sample of
    ``sim`` before true time ``t_end_s``; sequence numbers run on from ``seq0`` (mod 2^16),
    device ``t_us`` wraps at 2^32 as on the wire."""
    from host.wire.frames import encode_imu_samples

    seq = seq0
    while sim.t_next < t_end_s:
        block = sim.run_until(min(t_end_s, sim.t_next + chunk_s))
        if len(block):
            yield encode_imu_samples(seq, block.t_us, block.counts, block.flags)
            seq = (seq + len(block)) & 0xFFFF


@dataclass(frozen=True)
class TruthSeries:
    """The physical stimulus on a time grid: ``t_s`` (N,) s since power-on,
    ``specific_force`` (N, 3) m/s² and ``rate_dps`` (N, 3) °/s in body axes, ``temp_c`` (N,)."""

    t_s: np.ndarray
    specific_force: np.ndarray
    rate_dps: np.ndarray
    temp_c: np.ndarray


def truth_series(
    scenario: Scenario,
    t_s: np.ndarray,
    bench: Bench | None = None,
    environment: Environment | None = None,
    truth: SensorTruth | None = None,
    apply_errors: bool = False,
) -> TruthSeries:
    """The stimulus a sensor sees at times ``t_s`` for a motion schedule (for the emulated
    board: it feeds these to its virtual MPU-6000).

    With ``truth`` its lever arm enters the specific force; ``apply_errors`` also passes the
    inputs through the deterministic part of the error model (no noise, no quantisation), so
    the series is what an imperfect sensor would output.
    """
    bench = bench or Bench()
    environment = environment or Environment()
    t = np.asarray(t_s, dtype=np.float64)
    f = np.zeros((t.shape[0], 3))
    w = np.zeros((t.shape[0], 3))
    starts = np.array([s for s, _ in scenario]) if scenario else np.zeros(0)
    idx = np.searchsorted(starts, t, side="right") - 1
    lever = np.asarray(truth.lever_arm_m) if truth is not None else None
    for i in np.unique(idx):
        sel = idx == i
        motion = scenario[i][1] if i >= 0 else static_motion("z_up")
        f[sel], w[sel] = body_inputs(motion, t[sel], bench, lever)
    temp = environment.temperature(t)
    if apply_errors and truth is not None:
        f, w = sensor_output(truth, f, w, temp, t, bench.g)
    return TruthSeries(t, f, w, temp)
