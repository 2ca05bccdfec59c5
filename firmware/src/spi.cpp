#include "spi.hpp"

#include <avr/io.h>

#include "board.hpp"

namespace spi {

namespace {
// SPCR for SPI mode 3 (CPOL = 1: SCK idles high; CPHA = 1: sample on the trailing = rising
// edge), master, MSB first. ATmega2560 datasheet section 21 (SPI), tables 21-3/21-5.
constexpr uint8_t kSpcrMode3 = _BV(SPE) | _BV(MSTR) | _BV(CPOL) | _BV(CPHA);
}  // namespace

void init() {
    // Chip selects high first (PORT before DDR: no low glitch when the pin becomes an output).
    BOARD_MPU_CS_PORT |= _BV(BOARD_MPU_CS_BIT);
    BOARD_MPU_CS_DDR |= _BV(BOARD_MPU_CS_BIT);  // PB0 = /SS stays an output: master mode holds
    BOARD_BARO_CS_PORT |= _BV(BOARD_BARO_CS_BIT);
    BOARD_BARO_CS_DDR |= _BV(BOARD_BARO_CS_BIT);
    // SCK idles high in mode 3: set the pin high before it becomes an output.
    PORTB |= _BV(BOARD_SPI_SCK_BIT);
    BOARD_SPI_DDR |= _BV(BOARD_SPI_SCK_BIT) | _BV(BOARD_SPI_MOSI_BIT);
    BOARD_SPI_DDR &= static_cast<uint8_t>(~_BV(BOARD_SPI_MISO_BIT));
    SPCR = kSpcrMode3 | _BV(SPR0);  // fosc/16
    SPSR = 0;
}

void begin(Speed speed) {
    if (speed == Speed::kSensor) {
        SPCR = kSpcrMode3;  // SPR1:0 = 00 with SPI2X: fosc/2 = 8 MHz
        SPSR = _BV(SPI2X);
    } else {
        SPCR = kSpcrMode3 | _BV(SPR0);  // SPR1:0 = 01, SPI2X = 0: fosc/16 = 1 MHz
        SPSR = 0;
    }
    BOARD_MPU_CS_PORT &= static_cast<uint8_t>(~_BV(BOARD_MPU_CS_BIT));
}

void end() {
    // /CS hold time after the last SCLK edge: 500 ns min (PS p.19, section 6.8, t_HD.CS).
    __builtin_avr_delay_cycles(8);
    BOARD_MPU_CS_PORT |= _BV(BOARD_MPU_CS_BIT);
}

uint8_t transfer(uint8_t out) {
    SPDR = out;
    while (!(SPSR & _BV(SPIF))) {
    }
    return SPDR;
}

}  // namespace spi
