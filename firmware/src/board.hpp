// ArduPilot Mega 2.5/2.6 (ATmega2560 @ 16 MHz) pin assignments used by this firmware.
// From ArduPilot's AVR HAL for the APM2 board (see /work/shared/reference/toolchain-notes.md).
#pragma once

#include <avr/io.h>

#ifndef F_CPU
#error "F_CPU must be defined (the Makefile passes -DF_CPU=16000000UL)"
#endif

// SPI0 (hardware SPI): SCK PB1, MOSI PB2, MISO PB3.
// MPU-6000 chip select: PB0 = Arduino D53 = the hardware /SS pin. It must stay an OUTPUT: an
// input /SS pulled low would drop the SPI peripheral out of master mode (ATmega2560 datasheet,
// section 21.3.2 "SS Pin Functionality").
#define BOARD_MPU_CS_PORT PORTB
#define BOARD_MPU_CS_DDR DDRB
#define BOARD_MPU_CS_BIT PB0
#define BOARD_SPI_DDR DDRB
#define BOARD_SPI_SCK_BIT PB1
#define BOARD_SPI_MOSI_BIT PB2
#define BOARD_SPI_MISO_BIT PB3

// MS5611 barometer chip select: PG1 = D40. Not used here: driven HIGH forever so the baro never
// answers on the shared bus.
#define BOARD_BARO_CS_PORT PORTG
#define BOARD_BARO_CS_DDR DDRG
#define BOARD_BARO_CS_BIT PG1

// MPU-6000 INT (data ready) -> PE6 = INT6 (ArduPilot's "pin 70"). PE6 has no pin-change
// interrupt; external interrupt 6 is configured in EICRB (ISC61:ISC60) and enabled in EIMSK.
#define BOARD_MPU_INT_DDR DDRE
#define BOARD_MPU_INT_PORT PORTE
#define BOARD_MPU_INT_BIT PE6
