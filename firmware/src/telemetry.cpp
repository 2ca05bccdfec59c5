#include "telemetry.hpp"

#include <avr/io.h>
#include <avr/pgmspace.h>
#include <avr/wdt.h>

#include "frame.hpp"
#include "protocol_gen.h"
#include "timebase.hpp"
#include "uart.hpp"

#ifndef FW_VERSION_MAJOR
#define FW_VERSION_MAJOR 0
#endif
#ifndef FW_VERSION_MINOR
#define FW_VERSION_MINOR 1
#endif
#ifndef FW_VERSION_PATCH
#define FW_VERSION_PATCH 0
#endif

static_assert(FW_VERSION_MAJOR >= 0 && FW_VERSION_MAJOR <= 255, "FW_VERSION_MAJOR is a u8");
static_assert(FW_VERSION_MINOR >= 0 && FW_VERSION_MINOR <= 255, "FW_VERSION_MINOR is a u8");
static_assert(FW_VERSION_PATCH >= 0 && FW_VERSION_PATCH <= 255, "FW_VERSION_PATCH is a u8");

// Captured in .init3, before the C runtime clears .bss; .noinit is never cleared.
static uint8_t g_mcusr_at_boot __attribute__((section(".noinit")));
extern "C" void imu_bench_capture_mcusr() __attribute__((naked, used, section(".init3")));
extern "C" void imu_bench_capture_mcusr() {
    g_mcusr_at_boot = MCUSR;
    MCUSR = 0;
    wdt_disable();  // a watchdog reset leaves the watchdog running; this firmware does not use it
}

namespace telemetry {

namespace {

#define IMU_BENCH_U32LE(v) \
    (uint8_t)((v) & 0xFF), (uint8_t)(((v) >> 8) & 0xFF), (uint8_t)(((v) >> 16) & 0xFF), \
        (uint8_t)(((v) >> 24) & 0xFF)

constexpr uint8_t kMode = IMU_BENCH_DMP ? PROTO_MODE_DMP : PROTO_MODE_RAW;

// Identity block in flash: what HELLO reports about the build, in one place a host tool can also
// find in an .elf/.hex before flashing (tests/firmware checks it). Layout:
//   "IMUB", fw major, minor, patch, protocol_version, spec fingerprint u32le, mode, baud u32le,
//   timer resolution ns u16le.
const uint8_t kIdentity[] PROGMEM __attribute__((used)) = {
    'I', 'M', 'U', 'B',
    FW_VERSION_MAJOR, FW_VERSION_MINOR, FW_VERSION_PATCH,
    PROTO_VERSION,
    IMU_BENCH_U32LE(PROTO_SPEC_FINGERPRINT),
    kMode,
    IMU_BENCH_U32LE(UART_BAUD),
    (uint8_t)(timebase::kResolutionNs & 0xFF), (uint8_t)(timebase::kResolutionNs >> 8),
};
enum IdentityOffset : uint8_t {
    kIdMajor = 4, kIdMinor = 5, kIdPatch = 6, kIdProto = 7, kIdFingerprint = 8, kIdMode = 12,
    kIdBaud = 13, kIdTimerRes = 17,
};
static_assert(sizeof(kIdentity) == 19, "identity block layout");

uint8_t id8(uint8_t off) { return pgm_read_byte(&kIdentity[off]); }
uint16_t id16(uint8_t off) { return pgm_read_word(&kIdentity[off]); }
uint32_t id32(uint8_t off) { return pgm_read_dword(&kIdentity[off]); }

uint8_t g_buf[frame::kMaxFrameLen];
uint16_t g_seq = 0;
uint16_t g_error_counts[8] = {};

uint32_t g_uptime_ms = 0;
uint32_t g_uptime_last_us = 0;

bool queue(uint8_t type, uint8_t len, bool wait) {
    const uint8_t n = frame::finish(g_buf, type, len, g_seq);
    if (wait) {
        while (!uart::try_write(g_buf, n)) {
            // The UDRE interrupt drains the ring: <= 256 bytes = 22 ms at 115200 baud.
        }
    } else if (!uart::try_write(g_buf, n)) {
        return false;
    }
    ++g_seq;
    return true;
}

}  // namespace

Counters g_counters = {};
bool g_stream_enabled = true;

uint8_t reset_cause() { return g_mcusr_at_boot; }

void tick(uint32_t now_us) {
    // Called on every main-loop wake-up (each UART byte interrupt wakes it), so the common case
    // must be cheap: nothing to do below a millisecond, and a 16-bit division (a quarter of the
    // cycles of a 32-bit one on the AVR) for the usual gaps of under 65 ms.
    const uint32_t elapsed = now_us - g_uptime_last_us;
    if (elapsed < 1000u) {
        return;
    }
    const uint32_t ms = elapsed < 0x10000ul ? static_cast<uint16_t>(elapsed) / 1000u
                                            : elapsed / 1000u;
    g_uptime_ms += ms;
    g_uptime_last_us += ms * 1000u;
}

uint32_t uptime_ms() { return g_uptime_ms; }

void send_hello() {
    mpu6000::Readback rb;
    mpu6000::read_config(&rb);
    proto_put_HELLO(frame::payload(g_buf), id8(kIdMajor), id8(kIdMinor), id8(kIdPatch),
                    id8(kIdProto), id32(kIdFingerprint), rb.who_am_i, rb.product_id, rb.accel_fs_sel,
                    rb.gyro_fs_sel, rb.dlpf_cfg, rb.smplrt_div, id8(kIdMode), id16(kIdTimerRes),
                    id32(kIdBaud), g_mcusr_at_boot,
                    (g_stream_enabled && mpu6000::streaming()) ? 1 : 0);
    queue(PROTO_TYPE_HELLO, PROTO_LEN_HELLO, true);
}

void send_status() {
    const uint8_t hw = uart::tx_high_water();
    proto_put_STATUS(frame::payload(g_buf), g_uptime_ms, g_counters.samples,
                     mpu6000::missed_count(), g_counters.dropped, g_counters.crc_errors,
                     g_counters.spi_faults, g_counters.fifo_overflows,
                     static_cast<uint8_t>(hw / 4), mpu6000::bad_bursts(),
                     mpu6000::bus_flags());
    queue(PROTO_TYPE_STATUS, PROTO_LEN_STATUS, true);
}

void send_error(uint8_t code, uint8_t detail) {
    uint16_t count = 0;
    if (code < sizeof(g_error_counts) / sizeof(g_error_counts[0])) {
        count = ++g_error_counts[code];
    }
    proto_put_ERROR(frame::payload(g_buf), code, detail, count);
    queue(PROTO_TYPE_ERROR, PROTO_LEN_ERROR, true);
}

void send_ack(uint8_t cmd_type, uint16_t cmd_seq, uint8_t status) {
    proto_put_ACK(frame::payload(g_buf), cmd_type, cmd_seq, status);
    queue(PROTO_TYPE_ACK, PROTO_LEN_ACK, true);
}

void send_pong(uint32_t nonce, uint32_t t_us) {
    proto_put_PONG(frame::payload(g_buf), nonce, t_us);
    queue(PROTO_TYPE_PONG, PROTO_LEN_PONG, true);
}

void send_self_test(const mpu6000::SelfTestResult& r) {
    const int16_t(&m)[3][6] = r.mean;
    proto_put_SELF_TEST_RESULT(frame::payload(g_buf), r.status, r.trim[0], r.trim[1], r.trim[2],
                               r.trim[3], r.samples, m[0][0], m[0][1], m[0][2], m[0][3], m[0][4],
                               m[0][5], m[1][0], m[1][1], m[1][2], m[1][3], m[1][4], m[1][5],
                               m[2][0], m[2][1], m[2][2], m[2][3], m[2][4], m[2][5]);
    queue(PROTO_TYPE_SELF_TEST_RESULT, PROTO_LEN_SELF_TEST_RESULT, true);
}

bool send_sample(const mpu6000::Sample& sample, uint8_t flags) {
    const uint8_t n = frame::encode_imu_sample(g_buf, g_seq, sample.t_us, sample.raw, flags);
    if (!uart::try_write(g_buf, n)) {
        ++g_counters.dropped;
        return false;
    }
    ++g_seq;
    return true;
}

#if IMU_BENCH_DMP
bool send_quat(uint32_t t_us, const int32_t q[4]) {
    proto_put_DMP_QUAT(frame::payload(g_buf), t_us, q[0], q[1], q[2], q[3]);
    return queue(PROTO_TYPE_DMP_QUAT, PROTO_LEN_DMP_QUAT, false);
}
#endif

}  // namespace telemetry
