#include "uart.hpp"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

namespace uart {

namespace {

// Double-speed mode (U2X0): UBRR = F_CPU / (8 * baud) - 1, rounded (ATmega2560 datasheet
// table 22-1). 115200 -> 16 (+2.1 %), 500000 -> 3 and 1000000 -> 1 (exact).
constexpr uint32_t kUbrr = (F_CPU + 4UL * kBaud) / (8UL * kBaud) - 1UL;
constexpr uint32_t kActualBaud = F_CPU / (8UL * (kUbrr + 1UL));
constexpr uint32_t kErrorPermille =
    (kActualBaud > kBaud ? kActualBaud - kBaud : kBaud - kActualBaud) * 1000UL / kBaud;
static_assert(kUbrr <= 4095, "UART_BAUD too low for U2X at this F_CPU");
static_assert(kErrorPermille <= 25, "UART_BAUD error above 2.5 % at this F_CPU");

// Rings indexed by free-running uint8_t counters: the 256-byte TX ring wraps for free.
// Single producer (main loop) / single consumer (ISR): the producer only writes the head,
// the consumer only the tail, both single bytes (atomic on AVR).
constexpr uint16_t kTxSize = 256;
constexpr uint8_t kRxSize = 128;
constexpr uint8_t kRxMask = kRxSize - 1;
static_assert((kRxSize & kRxMask) == 0, "RX ring size must be a power of two");

uint8_t g_tx_buf[kTxSize];
volatile uint8_t g_tx_head = 0;  // next byte to write (main loop)
volatile uint8_t g_tx_tail = 0;  // next byte to send (ISR)
uint8_t g_tx_high_water = 0;

uint8_t g_rx_buf[kRxSize];
volatile uint8_t g_rx_head = 0;  // ISR
volatile uint8_t g_rx_tail = 0;  // main loop
volatile uint16_t g_rx_overruns = 0;

}  // namespace

void init() {
    // U2X0 must be set BEFORE UBRR: simavr computes the bit rate when UBRR0L is written.
    UCSR0A = _BV(U2X0);
    UBRR0H = static_cast<uint8_t>(kUbrr >> 8);
    UBRR0L = static_cast<uint8_t>(kUbrr);
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);  // 8N1
    UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
}

uint8_t tx_free() {
    // One slot stays empty so that head == tail means "empty".
    return static_cast<uint8_t>(kTxSize - 1 - static_cast<uint8_t>(g_tx_head - g_tx_tail));
}

bool try_write(const uint8_t* data, uint8_t n) {
    if (n > tx_free()) {
        return false;
    }
    uint8_t head = g_tx_head;
    for (uint8_t i = 0; i < n; ++i) {
        g_tx_buf[head++] = data[i];
    }
    g_tx_head = head;  // publish
    const uint8_t used = static_cast<uint8_t>(head - g_tx_tail);
    if (used > g_tx_high_water) {
        g_tx_high_water = used;
    }
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { UCSR0B |= _BV(UDRIE0); }
    return true;
}

uint8_t tx_high_water() { return g_tx_high_water; }

bool rx_available() { return g_rx_tail != g_rx_head; }

bool read(uint8_t* byte) {
    const uint8_t tail = g_rx_tail;
    if (tail == g_rx_head) {
        return false;
    }
    *byte = g_rx_buf[tail];
    g_rx_tail = static_cast<uint8_t>((tail + 1) & kRxMask);
    return true;
}

uint16_t rx_overruns() {
    uint16_t n;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { n = g_rx_overruns; }
    return n;
}

}  // namespace uart

using namespace uart;

// Data register empty: send the next queued byte, or stop the interrupt when the ring is empty.
ISR(USART0_UDRE_vect) {
    const uint8_t tail = g_tx_tail;
    if (tail == g_tx_head) {
        UCSR0B &= static_cast<uint8_t>(~_BV(UDRIE0));
        return;
    }
    UDR0 = g_tx_buf[tail];
    g_tx_tail = static_cast<uint8_t>(tail + 1);
}

// Byte received: store it, or count it lost when the ring is full.
ISR(USART0_RX_vect) {
    const uint8_t byte = UDR0;
    const uint8_t head = g_rx_head;
    const uint8_t next = static_cast<uint8_t>((head + 1) & kRxMask);
    if (next == g_rx_tail) {
        g_rx_overruns = g_rx_overruns + 1;
        return;
    }
    g_rx_buf[head] = byte;
    g_rx_head = next;
}
