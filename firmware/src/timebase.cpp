#include "timebase.hpp"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

namespace timebase {

namespace detail {
volatile uint32_t g_overflow_us = 0;
}

void init() {
    TCCR1A = 0;             // normal mode, no output compare pins
    TCCR1B = _BV(CS11);     // clk/8: 2 MHz, 0.5 us per tick (ATmega2560 datasheet table 17-6)
    TCNT1 = 0;
    OCR1A = 2u * kTickUs;
    TIFR1 = _BV(TOV1) | _BV(OCF1A);  // clear stale flags (write 1 to clear)
    TIMSK1 = _BV(TOIE1) | _BV(OCIE1A);
}

uint32_t micros() {
    uint32_t t;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { t = micros_from_isr(); }
    return t;
}

}  // namespace timebase

// A few cycles of work every 32.768 ms.
ISR(TIMER1_OVF_vect) {
    timebase::detail::g_overflow_us = timebase::detail::g_overflow_us + timebase::detail::kOverflowUs;
}

// Wake-up tick: the next compare 10 ms later (Timer1 keeps running free: t_us is unaffected).
ISR(TIMER1_COMPA_vect) { OCR1A += 2u * timebase::kTickUs; }
