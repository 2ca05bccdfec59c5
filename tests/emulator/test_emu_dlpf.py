"""The emulated MPU-6000's DLPF and a sample's time stamp against the physical instant it
describes (issue 13: "the filter itself, with the datasheet's bandwidth and delay").

The chip filters every axis with the DLPF_CFG's bandwidth and delay (RM p.13). For a ramp, any
linear filter of unit DC gain lags by exactly its DC group delay, so each sample's counts say at
which physical instant the truth had that value; the firmware's time stamp (the data-ready edge)
minus the datasheet delay must be that instant. A sine at the table's bandwidth comes out at
-3 dB. The right firmware passes at every DLPF_CFG (built in); a firmware that stamps a
sample with the previous data-ready's time fails by a whole sample period. (The DLPF_CFG is
built into the firmware under test: a SET_RATE from the host would land at an emulated instant
that depends on how fast the host reacts.)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from emu_helpers import collect, of_type
from test_mutations import MUTANTS, Mutant, build, mutate

from host.bench.emulator import EmulatedBoard
from host.bench.stimulus import write_stimulus
from host.wire import sensor
from host.wire.frames import Frame

pytestmark = pytest.mark.emulator

#: RM p.13: DLPF_CFG -> (accel bandwidth Hz, delay ms, gyro bandwidth Hz, delay ms)
DLPF_TABLE = {
    0: (260.0, 0.0, 256.0, 0.98), 1: (184.0, 2.0, 188.0, 1.9), 2: (94.0, 3.0, 98.0, 2.8),
    3: (44.0, 4.9, 42.0, 4.8), 4: (21.0, 8.5, 20.0, 8.3), 5: (10.0, 13.8, 10.0, 13.4),
    6: (5.0, 19.0, 5.0, 18.6),
}  # fmt: skip
SECONDS = 4.0  # emulated: bring-up (0.35 s), settling, then the measured part
SETTLE_S = 2.0  # the DLPF 6 transient after the configuration (decay ≈ 0.24 s) has died out
RECORD_HZ = 20_000.0  # stimulus records: their sample-and-hold lags by half a record
HOLD_S = 0.5 / RECORD_HZ
#: ramps (y, z axes): units per s, and the value at t = 0
ACCEL_RAMP = (np.array([0.0, 3.0, -3.2]), np.array([0.0, -8.0, 8.5]))  # m/s² per s, m/s²
GYRO_RAMP = (np.array([0.0, 70.0, -80.0]), np.array([0.0, -190.0, 210.0]))  # °/s per s, °/s
SINE_AMPL = (5.0, 100.0)  # x axis: m/s², °/s
#: the chip's sample instant - datasheet delay - physical instant: 0 (the hold is taken out);
#: per sample ± 1/2 LSB of the ramp (up to 100 µs: accel y, 1/16384 g at 3 m/s² per s) and
#: ± half a stimulus record (25 µs); where in that band the samples fall depends on the phase
#: of the sample clock, which moves with the firmware's bring-up time
MODEL_TOL_S = 60e-6
SPREAD_TOL_S = 130e-6
#: time stamp - the chip's sample instant: the data-ready interrupt's latency (~15 µs) minus
#: the device clock's origin (its timer starts ~0.24 ms after the emulated CPU: C start-up and
#: init), the same for every sample
STAMP_RANGE_S = (-400e-6, 100e-6)


@pytest.fixture(scope="module")
def stimulus_for(tmp_path_factory: pytest.TempPathFactory):  # noqa: ANN201 - a factory
    made: dict[int, Path] = {}

    def make(cfg: int) -> Path:
        if cfg not in made:
            abw, _, gbw, _ = DLPF_TABLE[cfg]
            t = np.arange(0.0, SECONDS + 0.5, 1.0 / RECORD_HZ)
            f = ACCEL_RAMP[1] + np.outer(t, ACCEL_RAMP[0])
            w = GYRO_RAMP[1] + np.outer(t, GYRO_RAMP[0])
            f[:, 0] = SINE_AMPL[0] * np.sin(2 * np.pi * abw * t)
            w[:, 0] = SINE_AMPL[1] * np.sin(2 * np.pi * gbw * t)
            path = tmp_path_factory.mktemp("dlpf") / f"cfg{cfg}.stim"
            write_stimulus(path, t, f, w, 30.0)
            made[cfg] = path
        return made[cfg]

    return make


def firmware_with_dlpf(cfg: int, workdir: Path) -> Path:
    """The firmware built with DLPF_CFG ``cfg`` (and 50 Hz: SMPLRT_DIV 159 at the 8 kHz internal
    rate of DLPF_CFG 0) instead of the calibration mode's 4 (a SET_RATE from the host would land
    at an emulated instant that depends on how fast the host reacts)."""
    div = 159 if cfg == 0 else 19
    edits = (("mpu6000.cpp", "kCfgDlpf = DLPF_CFG_20HZ;", f"kCfgDlpf = {cfg};"),
             ("mpu6000.cpp", "kDefaultSmplrtDiv = 19", f"kDefaultSmplrtDiv = {div}"))  # fmt: skip
    return build(mutate(workdir / "fw", Mutant(f"dlpf_{cfg}", "", edits)))


def run(emu_bin: Path, elf: Path, stim: Path, workdir: Path) -> tuple[list[Frame], np.ndarray]:
    """Run the board for SECONDS: the IMU_SAMPLE frames from SETTLE_S on, and the instant (s,
    emulated time) the chip made each of them (its sample log)."""
    with EmulatedBoard(elf, emulator=emu_bin, stimulus=stim, seconds=SECONDS, samplelog=True,
                       workdir=workdir) as board:  # fmt: skip
        frames = collect(board, max_wall_s=90)
        log = board.samplelog()
    samples = of_type(frames, "IMU_SAMPLE")
    made = log[log["read"] == 1]["t_us"] * 1e-6  # every frame is one of these, in order
    assert len(made) >= len(samples)
    keep = [k for k in range(len(samples)) if made[k] >= SETTLE_S]
    return [samples[k] for k in keep], made[keep]


def instant_errors(samples: list[Frame], cfg: int, t: np.ndarray | None = None) -> np.ndarray:
    """(N, 4) seconds: time stamp (or ``t``) - datasheet delay - the physical instant each ramp
    axis's counts describe (accel y, z, gyro y, z)."""
    _, a_delay, _, g_delay = (v * 1e-3 if i % 2 else v for i, v in enumerate(DLPF_TABLE[cfg]))
    if t is None:
        t = np.array([f.fields["t_us"] for f in samples], dtype=np.float64) * 1e-6
    out = []
    for axis in (1, 2):
        a = sensor.accel_mps2(np.array([f.fields["a" + "xyz"[axis]] for f in samples]))
        instant = (a - ACCEL_RAMP[1][axis]) / ACCEL_RAMP[0][axis]
        out.append(t - a_delay - instant - HOLD_S)
    for axis in (1, 2):
        g = sensor.gyro_dps(np.array([f.fields["g" + "xyz"[axis]] for f in samples]))
        instant = (g - GYRO_RAMP[1][axis]) / GYRO_RAMP[0][axis]
        out.append(t - g_delay - instant - HOLD_S)
    return np.column_stack(out)


def sine_gain(samples: list[Frame], field: str, freq_hz: float, ampl: float, scale) -> float:
    """Amplitude of ``field`` at ``freq_hz`` (least squares on the sample instants, aliased or
    not) over the stimulus amplitude."""
    t = np.array([f.fields["t_us"] for f in samples], dtype=np.float64) * 1e-6
    y = scale(np.array([f.fields[field] for f in samples]))
    basis = np.column_stack([np.sin(2 * np.pi * freq_hz * t), np.cos(2 * np.pi * freq_hz * t),
                             np.ones_like(t)])  # fmt: skip
    coef, *_ = np.linalg.lstsq(basis, y, rcond=None)
    return float(np.hypot(coef[0], coef[1]) / ampl)


@pytest.mark.slow
@pytest.mark.timeout(120)  # one short emulator run per DLPF_CFG
@pytest.mark.parametrize("cfg", sorted(DLPF_TABLE))
def test_time_stamp_minus_the_datasheet_delay_is_the_physical_instant(
    emu_bin: Path, emu_toolchain: None, fw_elf: Path, tmp_path: Path, stimulus_for, cfg: int
) -> None:
    elf = fw_elf if cfg == 4 else firmware_with_dlpf(cfg, tmp_path)
    samples, made = run(emu_bin, elf, stimulus_for(cfg), tmp_path)
    assert len(samples) >= (SECONDS - SETTLE_S) * 50 - 1
    # the chip: a sample made at t describes the physical instant t - the datasheet's delay
    model = instant_errors(samples, cfg, made)
    m_median = np.median(model, axis=0)
    assert np.all(np.abs(m_median) < MODEL_TOL_S), f"DLPF_CFG {cfg}: model {m_median * 1e6} µs"
    spread = np.max(np.abs(model - m_median), axis=0)
    assert np.all(spread < SPREAD_TOL_S), f"DLPF_CFG {cfg}: spread {spread * 1e6} µs"
    # the firmware: its time stamp - the datasheet's delay is that instant, up to a constant
    err = instant_errors(samples, cfg)
    median = np.median(err, axis=0)
    lo, hi = STAMP_RANGE_S
    assert np.all((lo < median) & (median < hi)), f"DLPF_CFG {cfg}: stamps {median * 1e6} µs"
    assert np.all(np.max(np.abs(err - median), axis=0) < SPREAD_TOL_S)
    print(f"\nDLPF_CFG {cfg}: model {m_median * 1e6} µs, stamps {median * 1e6} µs")
    # and the bandwidth: a sine at the table's -3 dB frequency comes out at 1/√2
    abw, a_delay, gbw, _ = DLPF_TABLE[cfg]
    if a_delay > 0:  # DLPF_CFG 0's accelerometer: 0 ms in the table, not filtered in the model
        gain = sine_gain(samples, "ax", abw, SINE_AMPL[0], sensor.accel_mps2)
        assert gain == pytest.approx(np.sqrt(0.5), abs=0.03), f"accel at {abw} Hz"
    gain = sine_gain(samples, "gx", gbw, SINE_AMPL[1], sensor.gyro_dps)
    assert gain == pytest.approx(np.sqrt(0.5), abs=0.03), f"gyro at {gbw} Hz"


#: a firmware that stamps each sample with the previous data-ready's time (the mutation suite's)
STAMPS_PREVIOUS_EDGE = next(m for m in MUTANTS if m.name == "timestamp_of_previous_data_ready")


@pytest.mark.timeout(120)  # one firmware build and one short emulator run
def test_a_firmware_stamping_the_previous_data_ready_fails_the_check(
    emu_bin: Path, emu_toolchain: None, tmp_path: Path, stimulus_for
) -> None:
    elf = build(mutate(tmp_path / "fw", STAMPS_PREVIOUS_EDGE))
    samples, _ = run(emu_bin, elf, stimulus_for(4), tmp_path)
    median = np.median(instant_errors(samples, 4), axis=0)
    # every sample is stamped one 20 ms period before the data-ready that announced it
    assert np.all(median < STAMP_RANGE_S[0])
    np.testing.assert_allclose(median, -0.020, atol=0.5e-3)
