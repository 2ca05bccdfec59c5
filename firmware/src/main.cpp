// IMU calibration bench firmware for the ArduPilot Mega 2.6 (ATmega2560 @ 16 MHz, MPU-6000).
//
// Streams raw MPU-6000 counts (IMU_SAMPLE frames, protocol/spec.json) over UART0; the host does
// the physics. Interrupts only timestamp and move bytes; everything else happens here, in one
// cooperative loop:
//   1. host commands: UART RX ring -> frame parser (sync/len/CRC) -> commands::handle
//   2. sensor: mpu6000::poll advances the bring-up state machine / supervises streaming / runs
//      the self-test (SELF_TEST_RESULT when it ends)
//   3. samples: a pending data-ready -> 14-byte burst read -> IMU_SAMPLE -> UART TX ring
//   4. STATUS once a second
//   5. sleep (idle mode) until the next interrupt when there is nothing to do
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>

#include "commands.hpp"
#include "frame.hpp"
#include "mpu6000.hpp"
#include "protocol_gen.h"
#include "spi.hpp"
#include "telemetry.hpp"
#include "timebase.hpp"
#include "uart.hpp"

namespace {

frame::Parser g_parser;

void on_command(void* ctx, uint8_t type, uint16_t seq, const uint8_t* payload, uint8_t len) {
    if (commands::handle(type, seq, payload, len).config_changed) {
        *static_cast<bool*>(ctx) = true;
    }
}

void service_commands(bool* config_changed) {
    uint8_t byte;
    while (uart::read(&byte)) {
        g_parser.feed(byte, on_command, config_changed);
    }
    telemetry::g_counters.crc_errors = g_parser.crc_errors();
}

// Sleep until any interrupt (data-ready, UART, the 10 ms Timer1 tick) unless
// there is work already. Interrupts are off while deciding so a wake-up cannot be lost: SEI
// takes effect after the following instruction, which is SLEEP.
void idle_until_interrupt() {
    cli();
    if (mpu6000::idle() && !mpu6000::sample_pending() && !uart::rx_available()) {
        sleep_enable();
        sei();
        sleep_cpu();
        sleep_disable();
    }
    sei();
}

}  // namespace

int main() {
    spi::init();
    uart::init();
    timebase::init();
    mpu6000::init();
    set_sleep_mode(SLEEP_MODE_IDLE);  // peripherals and timers keep running
    sei();

    bool hello_sent = false;      // HELLO once after reset, when the first bring-up attempt ends
    bool config_changed = false;  // SET_RATE applied; flag the next sample sent
    uint8_t fifo_flag = 0;        // DMP FIFO overflowed; flag the next sample sent
    uint32_t last_status_ms = 0;

    for (;;) {
        const uint32_t now = timebase::micros();
        telemetry::tick(now);

        service_commands(&config_changed);

        const mpu6000::Event ev = mpu6000::poll(now);
        if (ev.kind != mpu6000::Event::kNone && !hello_sent) {
            hello_sent = true;
            telemetry::send_hello();
        }
        if (ev.kind == mpu6000::Event::kSelfTestDone) {
            telemetry::send_self_test(mpu6000::self_test_result());
            config_changed = ev.code == 0;  // streaming again at the restored configuration
        }
        if (ev.kind == mpu6000::Event::kError ||
            (ev.kind == mpu6000::Event::kSelfTestDone && ev.code != 0)) {
            ++telemetry::g_counters.spi_faults;
            telemetry::send_error(ev.code, ev.detail);
        }

        mpu6000::Sample sample;
        if (mpu6000::read_sample(&sample)) {
            ++telemetry::g_counters.samples;
#if IMU_BENCH_DMP
            int32_t q[4];
            bool overflow = false;
            if (mpu6000::read_dmp_quat(q, &overflow) && telemetry::g_stream_enabled) {
                telemetry::send_quat(timebase::micros(), q);
            }
            if (overflow) {
                ++telemetry::g_counters.fifo_overflows;
                fifo_flag = PROTO_SAMPLE_FLAGS_FIFO_OVERFLOW;
            }
#endif
            if (telemetry::g_stream_enabled) {
                const uint8_t flags =
                    static_cast<uint8_t>((sample.missed ? PROTO_SAMPLE_FLAGS_MISSED : 0) |
                                         (config_changed ? PROTO_SAMPLE_FLAGS_CONFIG_CHANGED : 0) |
                                         fifo_flag);
                if (telemetry::send_sample(sample, flags)) {
                    config_changed = false;
                    fifo_flag = 0;
                }
            }
        }

        const uint32_t up = telemetry::uptime_ms();
        if (up - last_status_ms >= 1000u) {
            last_status_ms += 1000u;
            if (up - last_status_ms >= 1000u) {
                last_status_ms = up;  // fell behind (long stall): do not send a burst
            }
            telemetry::send_status();
        }

        idle_until_interrupt();
    }
}
