// SPI0 master for the MPU-6000: mode 3, polled (SPIF) from the main loop, never from an ISR.
#pragma once

#include <stdint.h>

namespace spi {

enum class Speed : uint8_t {
    kRegisters,  // fosc/16 = 1 MHz: the limit for writing/reading configuration registers
    kSensor,     // fosc/2 = 8 MHz: burst reads of sensor/interrupt registers (limit 20 MHz)
};

// Pins, both chip selects high, SPI enabled in master mode 3 at the slow clock.
void init();

// One transaction with the MPU-6000: begin() sets the clock and asserts /CS, end() releases it.
void begin(Speed speed);
void end();
uint8_t transfer(uint8_t out);

}  // namespace spi
