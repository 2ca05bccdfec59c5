// Harness self-test firmware for apm_emu (not the product firmware: that is firmware/src).
//
// Bare avr-libc, ATmega2560 @ 16 MHz, UART0 115200 (U2X). Brings the MPU-6000 up over SPI
// (registers at 1 MHz, sensor data at 8 MHz), streams IMU_SAMPLE frames (protocol/spec.json) on
// every INT6 rising edge, answers PING with PONG, sends HELLO after reset and ERROR
// SENSOR_ABSENT once a second while WHO_AM_I is wrong. Sleeps (idle) when there is nothing to do.
//
// Built with -DTESTAPP_BAD it breaks the board rules on purpose: registers written at 8 MHz and
// the baro /CS (PG1) left low, so the emulator's SPI-clock and bus-conflict checks must fire.
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <stdint.h>
#include <util/crc16.h>

#include "protocol_gen.h"

#define CS_LOW() (PORTB &= (uint8_t)~_BV(PB0))
#define CS_HIGH() (PORTB |= _BV(PB0))

static volatile uint16_t t1_ovf;
static volatile uint8_t drdy;
static volatile uint32_t drdy_t;
static uint16_t tx_seq;

ISR(TIMER1_OVF_vect) { t1_ovf++; }

static uint32_t micros(void) {  // Timer1 at fosc/8: 0.5 us per tick
    uint8_t s = SREG;
    cli();
    uint16_t lo = TCNT1;
    uint16_t hi = t1_ovf;
    if ((TIFR1 & _BV(TOV1)) && lo < 0x8000) hi++;
    SREG = s;
    return (((uint32_t)hi << 16) | lo) >> 1;
}

ISR(INT6_vect) {
    drdy_t = micros();
    drdy = 1;
}

// ---- UART (polled TX, interrupt-free RX polling)
static void uart_putc(uint8_t c) {
    while (!(UCSR0A & _BV(UDRE0))) {
    }
    UDR0 = c;
}

static void send_frame(uint8_t type, const uint8_t *p, uint8_t len) {
    uint8_t h[4] = {type, len, (uint8_t)tx_seq, (uint8_t)(tx_seq >> 8)};
    uint16_t crc = 0xFFFF;
    tx_seq++;
    uart_putc(PROTO_SYNC0);
    uart_putc(PROTO_SYNC1);
    for (uint8_t i = 0; i < 4; i++) {
        crc = _crc_xmodem_update(crc, h[i]);
        uart_putc(h[i]);
    }
    for (uint8_t i = 0; i < len; i++) {
        crc = _crc_xmodem_update(crc, p[i]);
        uart_putc(p[i]);
    }
    uart_putc((uint8_t)crc);
    uart_putc((uint8_t)(crc >> 8));
}

// ---- SPI
static void spi_speed(uint8_t fast) {
    if (fast) {
        SPCR = _BV(SPE) | _BV(MSTR) | _BV(CPOL) | _BV(CPHA);  // fosc/2 with SPI2X
        SPSR = _BV(SPI2X);
    } else {
        SPCR = _BV(SPE) | _BV(MSTR) | _BV(CPOL) | _BV(CPHA) | _BV(SPR0);  // fosc/16
        SPSR = 0;
    }
}

static uint8_t spi_xfer(uint8_t b) {
    SPDR = b;
    while (!(SPSR & _BV(SPIF))) {
    }
    return SPDR;
}

#ifdef TESTAPP_BAD
#define REG_FAST 1
#else
#define REG_FAST 0
#endif

static void wr(uint8_t reg, uint8_t v) {
    spi_speed(REG_FAST);
    CS_LOW();
    spi_xfer(reg);
    spi_xfer(v);
    CS_HIGH();
}

static uint8_t rd(uint8_t reg) {
    spi_speed(REG_FAST);
    CS_LOW();
    spi_xfer(reg | 0x80);
    uint8_t v = spi_xfer(0);
    CS_HIGH();
    return v;
}

static void delay_ms(uint16_t ms) {
    uint32_t t0 = micros();
    while (micros() - t0 < (uint32_t)ms * 1000u) {
    }
}

int main(void) {
    uint8_t mcusr = MCUSR;
    MCUSR = 0;
    PORTB |= _BV(PB0);
    DDRB |= _BV(PB0) | _BV(PB1) | _BV(PB2);
#ifndef TESTAPP_BAD
    PORTG |= _BV(PG1);  // baro /CS high
#endif
    DDRG |= _BV(PG1);
    TCCR1A = 0;
    TCCR1B = _BV(CS11);  // fosc/8
    TIMSK1 = _BV(TOIE1);
    UCSR0A = _BV(U2X0);  // before UBRR (simavr computes the rate on the UBRR0L write)
    UBRR0H = 0;
    UBRR0L = 16;  // 115200 with U2X
    UCSR0B = _BV(TXEN0) | _BV(RXEN0);
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);
    EICRB = _BV(ISC61) | _BV(ISC60);  // INT6 rising edge
    set_sleep_mode(SLEEP_MODE_IDLE);
    sei();

    delay_ms(100);  // the MPU-6000's power-on reset (RM p.41): unreachable until then

    uint8_t who = 0;
    uint16_t absent = 0;
    for (;;) {
        who = rd(0x75);
        if (who == 0x68) break;
        uint8_t e[PROTO_LEN_ERROR];
        proto_put_ERROR(e, PROTO_ERROR_CODE_SENSOR_ABSENT, who, ++absent);
        send_frame(PROTO_TYPE_ERROR, e, sizeof e);
        delay_ms(1000);
    }
    wr(0x6B, 0x01);  // wake, PLL with X gyro
    delay_ms(30);    // gyroscope start-up time (PS p.12)
    wr(0x6A, 0x10);  // I2C_IF_DIS
    wr(0x19, 19);    // 50 Hz
    wr(0x1A, 4);     // DLPF 20 Hz
    wr(0x1B, 0);     // +-250 dps
    wr(0x1C, 0);     // +-2 g
    wr(0x38, 0x01);  // DATA_RDY_EN
    EIFR = _BV(INTF6);
    EIMSK |= _BV(INT6);

    uint8_t hello[PROTO_LEN_HELLO];
    proto_put_HELLO(hello, 0, 0, 1, PROTO_VERSION, PROTO_SPEC_FINGERPRINT, who, 0x58, 0, 0, 4, 19,
                    PROTO_MODE_RAW, 500, 115200, mcusr, 1);
    send_frame(PROTO_TYPE_HELLO, hello, sizeof hello);

    uint8_t rx[10];
    uint8_t rxn = 0;
    for (;;) {
        // PING (a5 5a 81 04 seq seq n0 n1 n2 n3 crc crc): answered without checking the CRC
        while (UCSR0A & _BV(RXC0)) {
            uint8_t b = UDR0;
            if ((rxn == 0 && b != PROTO_SYNC0) || (rxn == 1 && b != PROTO_SYNC1)) {
                rxn = (b == PROTO_SYNC0);
                if (rxn) rx[0] = b;
                continue;
            }
            rx[rxn++] = b;
            if (rxn == 10) {
                rxn = 0;
                if (rx[2] == PROTO_TYPE_PING) {
                    uint8_t pong[PROTO_LEN_PONG];
                    uint32_t nonce = rx[6] | (uint32_t)rx[7] << 8 | (uint32_t)rx[8] << 16 |
                                     (uint32_t)rx[9] << 24;
                    proto_put_PONG(pong, nonce, micros());
                    send_frame(PROTO_TYPE_PONG, pong, sizeof pong);
                }
            }
        }
        if (drdy) {
            cli();
            uint32_t t = drdy_t;
            drdy = 0;
            sei();
            uint8_t raw[14];
            spi_speed(1);
            CS_LOW();
            spi_xfer(0x3B | 0x80);
            for (uint8_t i = 0; i < 14; i++) raw[i] = spi_xfer(0);
            CS_HIGH();
            uint8_t p[PROTO_LEN_IMU_SAMPLE];
            int16_t v[7];
            for (uint8_t i = 0; i < 7; i++) v[i] = (int16_t)((uint16_t)raw[2 * i] << 8 | raw[2 * i + 1]);
            proto_put_IMU_SAMPLE(p, t, v[0], v[1], v[2], v[3], v[4], v[5], v[6], 0);
            send_frame(PROTO_TYPE_IMU_SAMPLE, p, sizeof p);
        }
        cli();
        if (!drdy && !(UCSR0A & _BV(RXC0))) {
            sleep_enable();
            sei();
            sleep_cpu();
            sleep_disable();
        }
        sei();
    }
}
