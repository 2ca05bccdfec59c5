// Device -> host frames (HELLO, STATUS, ERROR, ACK, PONG, SELF_TEST_RESULT, IMU_SAMPLE, DMP_QUAT) and the
// counters STATUS reports. Every emitted frame takes the next seq number; a frame that is not
// queued (a dropped sample) does not, so a gap in seq on the host means bytes lost in transit.
#pragma once

#include <stdint.h>

#include "mpu6000.hpp"

namespace telemetry {

struct Counters {
    uint32_t samples;        // data-ready events read from the sensor
    uint32_t dropped;        // samples read but not queued (UART ring full)
    uint16_t crc_errors;     // received command frames with a bad CRC
    uint16_t spi_faults;     // sensor faults: absent, config/DMP verify, SPI check, DRDY timeout
    uint16_t fifo_overflows; // DMP FIFO overflows
};

extern Counters g_counters;
extern bool g_stream_enabled;  // START_STREAM/STOP_STREAM; on after reset

// MCUSR as it was at boot (captured before main, then cleared).
uint8_t reset_cause();

// Keep the millisecond uptime; call every main-loop pass (at least once per 71 minutes).
void tick(uint32_t now_us);
uint32_t uptime_ms();

// Control frames wait for room in the UART ring (at most a few ms); they are never dropped.
void send_hello();
void send_status();
void send_error(uint8_t code, uint8_t detail);  // counts per code for ERROR.count
void send_ack(uint8_t cmd_type, uint16_t cmd_seq, uint8_t status);
void send_pong(uint32_t nonce, uint32_t t_us);
void send_self_test(const mpu6000::SelfTestResult& result);

// Data frames never wait: if the whole frame does not fit, it is dropped and counted.
bool send_sample(const mpu6000::Sample& sample, uint8_t flags);
#if IMU_BENCH_DMP
bool send_quat(uint32_t t_us, const int32_t q[4]);
#endif

}  // namespace telemetry
