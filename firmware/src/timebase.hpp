// Device time: Timer1 free-running at F_CPU/8 = 2 MHz (0.5 us per tick), extended to a 32-bit
// microsecond counter by the overflow interrupt (one every 65536 ticks = 32.768 ms).
//
// Timer1 compare A also interrupts every 10 ms (kTickUs): that ISR does nothing but wake the main
// loop from idle sleep, so timed work (bring-up delays, STATUS) runs within 10 ms of its time.
//
// Resolution: the hardware timer ticks every 500 ns (reported as HELLO.timer_resolution_ns);
// t_us values are that count / 2, i.e. whole microseconds, wrapping every 2^32 us (71.6 min).
#pragma once

#include <stdint.h>

#ifdef __AVR__
#include <avr/io.h>
#endif

namespace timebase {

static constexpr uint16_t kResolutionNs = 500;  // Timer1 prescaler 8 at 16 MHz
static constexpr uint16_t kTickUs = 10000;       // main-loop wake-up period

void init();

// Microseconds since init(); safe with interrupts on or off.
uint32_t micros();

#ifdef __AVR__
namespace detail {
// Microseconds at the last Timer1 overflow: the overflow ISR adds 32768 (65536 ticks of
// 0.5 us). Kept in microseconds rather than as an overflow count so that reading the time is
// one 32-bit add, not a 15-place shift of a 32-bit value (a loop on the AVR).
extern volatile uint32_t g_overflow_us;
static constexpr uint32_t kOverflowUs = 32768u;
}  // namespace detail

// For ISRs (interrupts already off): device time now. Accounts for an overflow that happened
// but whose interrupt is still pending (TOV1 set with a small count).
static inline uint32_t micros_from_isr() {
    uint16_t ticks = TCNT1;
    uint32_t base = detail::g_overflow_us;
    if ((TIFR1 & _BV(TOV1)) && ticks < 0x8000u) {
        base += detail::kOverflowUs;
    }
    return base + (ticks >> 1);
}
#endif

}  // namespace timebase
