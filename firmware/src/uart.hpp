// UART0 (the USB bridge on the APM): interrupt-driven transmit and receive rings, 8N1.
#pragma once

#include <stdint.h>

#ifndef UART_BAUD
#define UART_BAUD 115200UL
#endif

namespace uart {

static constexpr uint32_t kBaud = UART_BAUD;

void init();

// Queue all n bytes or none of them (never a partial frame). Never blocks.
bool try_write(const uint8_t* data, uint8_t n);

// Bytes that can be queued right now.
uint8_t tx_free();

// Largest number of bytes ever waiting in the transmit ring.
uint8_t tx_high_water();

// Received bytes are waiting.
bool rx_available();

// One received byte, if any.
bool read(uint8_t* byte);

// Received bytes lost because the receive ring was full.
uint16_t rx_overruns();

}  // namespace uart
