// MPU-6000 driver: bring-up state machine, verified configuration, data-ready interrupt,
// sample burst reads and (in DMP builds) the DMP loader and FIFO reader.
//
// Everything here runs from the main loop except the INT6 ISR, which only timestamps.
#pragma once

#include <stdint.h>

#include "frame.hpp"

#ifndef IMU_BENCH_DMP
#define IMU_BENCH_DMP 0
#endif

namespace mpu6000 {

struct Event {
    enum Kind : uint8_t {
        kNone,
        kReady,  // bring-up finished: streaming from now on
        kError,  // a fault (code = PROTO_ERROR_CODE_*, detail): the driver retries in ~1 s
        kSelfTestDone,  // self_test_result() is ready; code != 0: also a fault (as kError)
    };
    Kind kind;
    uint8_t code;
    uint8_t detail;
};

struct Sample {
    uint32_t t_us;                     // latched in the data-ready ISR
    uint8_t raw[frame::kImuRawLen];    // ACCEL_XOUT_H..GYRO_ZOUT_L as read
    bool missed;                       // another data-ready came while this one was pending
};

struct Readback {
    uint8_t who_am_i;
    uint8_t product_id;  // PRODUCT_ID as read at the last bring-up
    uint8_t accel_fs_sel;
    uint8_t gyro_fs_sel;
    uint8_t dlpf_cfg;
    uint8_t smplrt_div;
};

enum class RateResult : uint8_t { kOk, kBadArgument, kBusy, kVerifyFailed };

// The self-test's raw result (SELF_TEST_RESULT): the factory trim registers and the mean counts
// of three windows at the self-test ranges (+-8 g, +-250 deg/s): off, on, off again.
struct SelfTestResult {
    uint8_t status;      // PROTO_SELF_TEST_STATUS_*
    uint8_t trim[4];     // SELF_TEST_X, _Y, _Z, _A as read
    uint8_t samples;     // samples averaged per window
    int16_t mean[3][6];  // [window][ax ay az gx gy gz]
};

enum class SelfTestStart : uint8_t { kStarted, kBusy, kUnsupported };

// Pins and the INT6 sense; starts the bring-up from scratch.
void init();

// Advance the bring-up / supervise streaming. Call every main-loop pass; never blocks for long
// (at most one 16-byte DMP chunk or one config-table pass at 1 MHz).
Event poll(uint32_t now_us);

bool streaming();

// True when poll() has nothing to do until time passes or an interrupt arrives (waiting,
// streaming or in fault back-off): the main loop may sleep until the next interrupt.
bool idle();

// A data-ready is waiting for read_sample().
bool sample_pending();

// Take the pending sample, if any: copies its timestamp and flags, clears the pending flag and
// burst-reads INT_STATUS + the 14 sensor bytes at 8 MHz (1 MHz after a bad burst). A burst
// that fails the check is dropped (false; the next sample is flagged missed).
bool read_sample(Sample* out);

// Data-ready events not serviced before the next one, since reset.
uint32_t missed_count();

// Sensor bursts that failed the check (INT_STATUS without data-ready, or 14 equal bytes),
// since reset; each was dropped.
uint16_t bad_bursts();

// PROTO_STATUS_FLAGS_* bits: SPI_LOW_CLOCK once a bad burst made the driver read the sensor
// at 1 MHz (until reset).
uint8_t bus_flags();

// SET_RATE: new SMPLRT_DIV and DLPF_CFG through the verified config path. On kVerifyFailed
// *bad_register says which register read back wrong; the driver restarts its bring-up.
RateResult set_rate(uint8_t smplrt_div, uint8_t dlpf_cfg, uint8_t* bad_register);

// Current WHO_AM_I and configuration, read from the chip now (for HELLO); during a self-test
// the configuration it will return to.
void read_config(Readback* out);

// SELF_TEST: start the self-test (only while streaming; not in DMP builds). poll() then runs
// it without blocking and returns kSelfTestDone when self_test_result() holds the outcome and
// the configuration is restored (or, on a fault, the bring-up starts again).
SelfTestStart start_self_test();
const SelfTestResult& self_test_result();

#if IMU_BENCH_DMP
// One DMP quaternion from the FIFO if a whole packet is there. *overflow is set when the FIFO
// overflowed (it is then reset and no quaternion is returned).
bool read_dmp_quat(int32_t q[4], bool* overflow);
#endif

}  // namespace mpu6000
