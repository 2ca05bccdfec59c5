// apm_emu: an emulated ArduPilot Mega 2.6 (ATmega2560 @ 16 MHz + MPU-6000 on SPI) on libsimavr.
//
// Loads a firmware ELF, attaches an MPU-6000 register model to SPI0 (/CS = PB0, INT -> PE6/INT6),
// feeds it physical truth from a stimulus stream, and bridges UART0 to a pseudo-terminal.
// Usage and file formats: README.md beside this file; `apm_emu --help`.
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <math.h>
#include <poll.h>
#include <pty.h>
#include <sys/inotify.h>
#include <sys/ioctl.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <avr_extint.h>
#include <avr_ioport.h>
#include <avr_spi.h>
#include <avr_uart.h>
#include <sim_avr.h>
#include <sim_elf.h>
#include <sim_hex.h>
#include <sim_irq.h>
#include <sim_regbit.h>
#include <sim_time.h>

#include "mpu6000.h"
#include "stimulus.h"

// ATmega2560 data-space addresses (avr/iom2560.h)
#define A_DDRB 0x24
#define A_PORTB 0x25
#define A_DDRG 0x33
#define A_PORTG 0x34
#define A_MCUSR 0x54
#define A_SPCR 0x4C
#define A_EIMSK 0x3D
#define A_EICRB 0x6A
#define SPCR_DORD 0x20
#define SPCR_CPOL 0x08
#define SPCR_CPHA 0x04

enum { FAULT_NONE, FAULT_ABSENT, FAULT_STUCK_MISO, FAULT_NO_DRDY, FAULT_MARGINAL_BUS };
static const char *FAULT_NAMES[] = {"none", "absent", "stuck-miso", "no-drdy", "marginal-bus"};
// marginal bus: above this SCLK, MISO misses the AVR's setup time (a long or loaded cable)
#define MARGINAL_BUS_MAX_HZ 1e6
static const dmp_image_desc_t DMP_IMAGES[] = {DMP_IMAGE_DESC_MOTIONAPPS20, DMP_IMAGE_DESC_EMD6};

#define RXQ_SIZE 8192
#define TXBUF_SIZE 4096
#define POLL_PERIOD_US 1000
#define DEFAULT_BOOTLOADER \
    "/usr/share/arduino/hardware/arduino/avr/bootloaders/stk500v2/stk500boot_v2_mega2560.hex"

static struct {
    // options
    const char *profile_path;
    const char *elf, *hex, *bootloader, *flash_file;  // --boot: bootloader = DEFAULT_BOOTLOADER
    const char *stimulus, *reglog_path, *samplelog_path, *pty_file, *summary_file;
    double seconds;  // 0: until the stimulus ends (or until stopped, without one)
    int realtime, wait_open, dtr_reset, spi_fixed_timing, quiet, boot;
    int fault;
    double fault_at;
    double noise_accel, noise_gyro, clock_ppm;
    uint64_t seed;
    unsigned dmp_packet;
    unsigned product_id;               // --product-id: what PRODUCT_ID reads
    int self_test_fail;                // --self-test fail: the part fails its self-test
    const dmp_image_desc_t *dmp_desc;  // --dmp-image: check the load sequence against it

    avr_t *avr;
    avr_spi_t *spi;
    avr_uart_t *uart;
    avr_irq_t *irq_spi_in, *irq_uart_in, *irq_int;
    uint64_t freq;

    mpu6000_t mpu;
    stim_t stim;
    FILE *reglog, *samplelog;

    // pty
    int master;
    char pty_name[128];
    int connected;
    int ino;       // inotify on the pty slave: IN_OPEN / IN_CLOSE tell host opens exactly
    int opens;     // how many host file descriptors have the slave open
    int started;   // the AVR has been started (opens after this are DTR resets)
    double hold_until;  // wall time before which the AVR stays in reset (start-up delay)
    uint8_t rxq[RXQ_SIZE];
    unsigned rxq_head, rxq_len;
    int rx_pump_running, uart_xoff;
    uint8_t txbuf[TXBUF_SIZE];
    unsigned txlen;

    // state
    volatile sig_atomic_t stop_signal;
    volatile int done;
    int reset_requested;
    const char *stop_reason;
    int int_asserted;
    double sample_next_exact;  // absolute cycle of the next sample-clock tick; <0: stopped
    double filt_last_t;        // emulated time of the last DLPF (internal-rate) step; <0: none
    int txn_conflict;
    uint8_t spi_prev_mosi_lsb;  // last MOSI bit of the previous byte (wrong SPI mode model)
    uint8_t spi_prev_miso_lsb;  // last MISO bit of the previous byte (marginal bus model)
    uint64_t garbled_bytes;     // MISO bytes the marginal bus corrupted
    uint64_t last_drdy_cycle, last_drdy_idx;
    uint64_t rng;

    // accounting
    uint64_t start_cycle;
    double wall_start;
    uint64_t sleep_cycles;
    uint64_t spi_violations, bus_conflicts, spi_bytes, reg_accesses, cs_transactions;
    uint64_t drdy_pulses, avr_resets, mpu_resets;
    uint64_t tx_bytes, tx_dropped, rx_bytes, rx_dropped;
    uint64_t latency_sum, latency_max, latency_n;
    uint64_t steady_cycle0, steady_sleep0, steady_read0;
    int steady_started;
    int first_violation_reg;
    double first_violation_t;

    // boot section / persistent flash
    uint32_t boot_start;       // byte address of the bootloader (reset vector with --boot)
    int in_boot;               // the CPU was in the boot section at the last poll tick
    double boot_wall0, boot_sim0;  // pacing reference: the bootloader runs in real time
    uint64_t boot_entries;     // times the CPU entered the boot section (resets into it)
    uint8_t *flash_saved;      // flash contents as last written to --flash-file
    uint64_t flash_saves;
} E;

static double wall_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static double sim_s(void) { return (double)(E.avr->cycle - E.start_cycle) / (double)E.freq; }

static int fault_now(void) {
    return (E.fault != FAULT_NONE && sim_s() >= E.fault_at) ? E.fault : FAULT_NONE;
}

static void die(const char *msg) {
    fprintf(stderr, "apm_emu: %s\n", msg);
    exit(2);
}

// ---------------------------------------------------------------- noise (splitmix64 + Box-Muller)
static double urand(void) {
    uint64_t z = (E.rng += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return ((double)(z >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

static double grand(void) { return sqrt(-2.0 * log(urand())) * cos(2.0 * M_PI * urand()); }

// ---------------------------------------------------------------- INT pin (PE6 = INT6)
static void drive_int(void) {
    int active_low = (E.mpu.reg[MPU_INT_PIN_CFG] & MPU_PIN_INT_LEVEL) != 0;
    avr_raise_irq(E.irq_int, (uint32_t)(E.int_asserted ^ active_low));
}

static avr_cycle_count_t int_pulse_end(avr_t *avr, avr_cycle_count_t when, void *param) {
    (void)avr, (void)when, (void)param;
    E.int_asserted = 0;
    drive_int();
    return 0;
}

static void assert_int(void) {
    // a pulsed INT needs INT6 on its leading edge (rising for active high, falling for active
    // low; ISC61:60 = 11 / 10, EICRB): the trailing edge comes 50 us later, "any edge" twice
    if ((E.avr->data[A_EIMSK] & (1 << 6)) &&
        !(E.mpu.reg[MPU_INT_PIN_CFG] & MPU_PIN_LATCH_INT_EN)) {
        unsigned isc = (E.avr->data[A_EICRB] >> 4) & 3;
        unsigned want = (E.mpu.reg[MPU_INT_PIN_CFG] & MPU_PIN_INT_LEVEL) ? 2 : 3;
        if (isc != want) {
            E.mpu.now_s = sim_s();
            mpu_violate(&E.mpu, MPU_RULE_DRDY_EDGE, -1);
        }
    }
    E.int_asserted = 1;
    drive_int();
    E.drdy_pulses++;
    if (!(E.mpu.reg[MPU_INT_PIN_CFG] & MPU_PIN_LATCH_INT_EN))  // 50 us pulse (RM p.26)
        avr_cycle_timer_register_usec(E.avr, 50, int_pulse_end, NULL);
}

// ---------------------------------------------------------------- sample log
static void on_retire(void *ctx, uint64_t idx, double t, const int16_t c[7], int read) {
    (void)ctx;
    if (E.samplelog)
        fprintf(E.samplelog, "%llu,%.6f,%d,%d,%d,%d,%d,%d,%d,%d\n", (unsigned long long)idx,
                t * 1e6, c[0], c[1], c[2], c[3], c[4], c[5], c[6], read);
}

// ---------------------------------------------------------------- MPU sample clock
static double sample_period_cycles(void) {
    return (double)mpu_period_ticks_8k(&E.mpu) * ((double)E.freq / 8000.0) *
           (1.0 + E.clock_ppm * 1e-6);
}

static avr_cycle_count_t sample_tick(avr_t *avr, avr_cycle_count_t when, void *param);

// The DLPF runs at the internal rate: step it through the instants since the last sample up to
// t (the sample clock divides the internal clock by 1 + SMPLRT_DIV, so a sample instant is
// always an internal step). Each step takes the stimulus its delay before its own instant.
static void dlpf_steps_until(double t) {
    unsigned n = 1u + E.mpu.reg[MPU_SMPLRT_DIV];
    double ts = (1.0 + E.clock_ppm * 1e-6) / mpu_internal_rate_hz(&E.mpu);
    for (unsigned j = n; j-- > 0;) {
        double tj = t - (double)j * ts;
        if (tj <= E.filt_last_t + 0.25 * ts) continue;  // stepped already (or before a wake)
        double da, dg;
        mpu_dlpf_delays(&E.mpu, &da, &dg);
        mpu_truth_t a, g;
        stim_at(&E.stim, tj, &a);  // advances the stream to tj: the delayed lookups look back
        stim_back(&E.stim, tj - da, &a);
        stim_back(&E.stim, tj - dg, &g);
        mpu_internal_tick(&E.mpu, &a, &g);
        E.filt_last_t = tj;
    }
}

static void sample_clock_schedule(void) {
    // (re)register at the absolute time sample_next_exact (survives AVR resets: the sensor is a
    // separate chip whose clock does not stop when the AVR resets)
    avr_cycle_count_t at = (avr_cycle_count_t)llround(E.sample_next_exact);
    avr_cycle_count_t now = E.avr->cycle;
    avr_cycle_timer_register(E.avr, at > now ? at - now : 1, sample_tick, NULL);
}

static void sample_clock_update(void) {
    if (mpu_awake(&E.mpu)) {
        // waking (or re-waking) restarts the divider: first sample one period from now
        E.sample_next_exact = (double)E.avr->cycle + sample_period_cycles();
        sample_clock_schedule();
        // the signal path starts from what it measures now: no step before this instant
        E.filt_last_t = sim_s();
        mpu_filter_reset(&E.mpu);
    } else {
        E.sample_next_exact = -1;
        avr_cycle_timer_cancel(E.avr, sample_tick, NULL);
    }
}

static avr_cycle_count_t sample_tick(avr_t *avr, avr_cycle_count_t when, void *param) {
    (void)param, (void)when;
    if (!mpu_awake(&E.mpu) || E.sample_next_exact < 0) return 0;
    double t = sim_s();
    dlpf_steps_until(t);
    mpu_truth_t truth;
    if (!stim_at(&E.stim, t, &truth) && E.seconds <= 0 && !E.done) {
        E.done = 1;
        E.stop_reason = "stimulus ended";
    }
    for (int i = 0; i < 3; i++) {  // what the DLPF made of it (temperature is not filtered)
        truth.f[i] = E.mpu.filtered[i];
        truth.w[i] = E.mpu.filtered[3 + i];
    }
    if (E.noise_accel > 0)
        for (int i = 0; i < 3; i++) truth.f[i] += E.noise_accel * grand();
    if (E.noise_gyro > 0)
        for (int i = 0; i < 3; i++) truth.w[i] += E.noise_gyro * grand();
    int f = fault_now();
    if (f != FAULT_ABSENT) {
        double period = sample_period_cycles();
        uint64_t ovf0 = E.mpu.fifo_overflows;
        uint8_t st0 = E.mpu.reg[MPU_INT_STATUS];
        E.mpu.now_s = t;
        mpu_sample(&E.mpu, &truth, period / (double)E.freq);
        uint8_t en = E.mpu.reg[MPU_INT_ENABLE];
        int event = (en & MPU_INT_DATA_RDY) ||
                    ((en & MPU_INT_FIFO_OFLOW) && E.mpu.fifo_overflows != ovf0) ||
                    ((en & MPU_INT_DMP) && (E.mpu.reg[MPU_INT_STATUS] & ~st0 & MPU_INT_DMP));
        if (event && f != FAULT_NO_DRDY) {
            assert_int();
            E.last_drdy_cycle = avr->cycle;
            E.last_drdy_idx = E.mpu.produced;
        }
    }
    E.sample_next_exact += sample_period_cycles();
    avr_cycle_count_t next = (avr_cycle_count_t)llround(E.sample_next_exact);
    return next > avr->cycle ? next : avr->cycle + 1;
}

// ---------------------------------------------------------------- SPI
static unsigned spi_divider(void) {
    static const unsigned div[4] = {4, 16, 64, 128};
    avr_t *avr = E.avr;
    unsigned d = div[(avr_regbit_get(avr, E.spi->spr[1]) << 1) | avr_regbit_get(avr, E.spi->spr[0])];
    if (avr_regbit_get(avr, E.spi->spr[2])) d /= 2;  // SPI2X
    return d;
}

static void handle_mpu_events(void) {
    unsigned ev = E.mpu.events;
    E.mpu.events = 0;
    if (ev & MPU_EV_RESET) E.mpu_resets++;
    if (ev & MPU_EV_CLOCK) sample_clock_update();
    if ((ev & MPU_EV_INT_CLEAR) && E.int_asserted &&
        (E.mpu.reg[MPU_INT_PIN_CFG] & MPU_PIN_LATCH_INT_EN)) {
        E.int_asserted = 0;
        drive_int();
    }
    if (ev & MPU_EV_RESET) {  // back to a 0x00 INT_PIN_CFG: active high, pulsed, pin released
        E.int_asserted = 0;
        avr_cycle_timer_cancel(E.avr, int_pulse_end, NULL);
    }
    if (ev & (MPU_EV_PIN_CFG | MPU_EV_RESET)) drive_int();
}

static uint8_t bitrev8(uint8_t b) {
    b = (uint8_t)((b & 0xF0) >> 4 | (b & 0x0F) << 4);
    b = (uint8_t)((b & 0xCC) >> 2 | (b & 0x33) << 2);
    return (uint8_t)((b & 0xAA) >> 1 | (b & 0x55) << 1);
}

// A byte the AVR shifted out on MOSI (SPI master): answer on MISO.
static void spi_out_cb(avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq, (void)param;
    E.spi_bytes++;
    if (!E.mpu.cs_low) return;  // MPU not selected: it does not drive MISO
    if (!(E.avr->data[A_PORTG] & (1 << 1))) E.txn_conflict = 1;  // baro /CS not high
    int f = fault_now();
    mpu_access_t acc;
    int has = 0;
    E.mpu.now_s = sim_s();
    // The chip latches MOSI on the rising SCLK edge and shifts MISO on the falling one, MSB
    // first (PS p.37). Mode 1/2 (CPOL != CPHA) makes both sides sample one bit off; DORD = 1
    // reverses every byte. The model sees (and answers) what the silicon would.
    uint8_t spcr = E.avr->data[A_SPCR];
    uint8_t mosi = (uint8_t)value;
    int bad_mode = !(spcr & SPCR_CPOL) != !(spcr & SPCR_CPHA);
    int lsb_first = (spcr & SPCR_DORD) != 0;
    if (bad_mode) {
        mpu_violate(&E.mpu, MPU_RULE_SPI_MODE, -1);
        mosi = (uint8_t)((mosi >> 1) | (E.spi_prev_mosi_lsb << 7));
    }
    E.spi_prev_mosi_lsb = (uint8_t)(value & 1);
    if (lsb_first) {
        mpu_violate(&E.mpu, MPU_RULE_SPI_BIT_ORDER, -1);
        mosi = bitrev8(mosi);
    }
    // (absent: the model still parses the bytes, for the register log, but nothing answers)
    uint8_t miso = mpu_spi_byte(&E.mpu, mosi, &acc, &has);
    if (bad_mode) miso = (uint8_t)(miso << 1);
    if (lsb_first) miso = bitrev8(miso);
    if (f == FAULT_STUCK_MISO) miso = 0xFF;
    if (f == FAULT_ABSENT) miso = 0x00;
    unsigned div = spi_divider();
    double hz = (double)E.freq / div;
    if (f == FAULT_MARGINAL_BUS && hz > MARGINAL_BUS_MAX_HZ) {
        // the AVR samples each MISO bit before the chip's edge reaches it: one bit late
        uint8_t late = (uint8_t)((E.spi_prev_miso_lsb << 7) | (miso >> 1));
        E.spi_prev_miso_lsb = miso & 1;
        if (late != miso) {
            E.garbled_bytes++;
            E.mpu.txn_garbled = 1;
        }
        miso = late;
    } else {
        E.spi_prev_miso_lsb = miso & 1;
    }
    if (has) {
        E.reg_accesses++;
        int viol = !mpu_is_sensor_reg(acc.reg) && hz > 1e6;
        if (viol) mpu_violate(&E.mpu, MPU_RULE_SPI_CLOCK, acc.reg);
        if (viol) {
            if (!E.spi_violations) {
                E.first_violation_reg = acc.reg;
                E.first_violation_t = sim_s();
            }
            E.spi_violations++;
        }
        if (E.reglog)
            fprintf(E.reglog, "%.3f,%c,0x%02X,0x%02X,%.0f,%d\n", sim_s() * 1e6,
                    acc.is_read ? 'R' : 'W', acc.reg, acc.is_read ? miso : acc.value,
                    hz, viol);
    }
    if (E.mpu.events) handle_mpu_events();
    if (f != FAULT_ABSENT) avr_raise_irq(E.irq_spi_in, miso);  // absent: SPDR reads 0x00
}

// simavr 1.6 completes every SPI byte 100 us after SPDR is written, whatever the divider. This
// replaces its SPDR write handler with the same logic and the real 8 x divider CPU cycles.
static avr_cycle_count_t spi_done(avr_t *avr, avr_cycle_count_t when, void *param) {
    (void)when;
    avr_spi_t *p = (avr_spi_t *)param;
    if (avr_regbit_get(avr, p->spe) && avr_regbit_get(avr, p->mstr)) {
        avr_raise_interrupt(avr, &p->spi);
        avr_raise_irq(p->io.irq + SPI_IRQ_OUTPUT, avr->data[p->r_spdr]);
    }
    return 0;
}

static void spdr_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param) {
    avr_spi_t *p = (avr_spi_t *)param;
    avr_regbit_clear(avr, p->spi.raised);
    avr_core_watch_write(avr, addr, v);
    avr_cycle_count_t c = E.spi_fixed_timing ? avr_usec_to_cycles(avr, 100) : 8u * spi_divider();
    avr_cycle_timer_register(avr, c, spi_done, p);
}

// PB0 = MPU-6000 /CS
static void cs_cb(avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq, (void)param;
    avr_t *avr = E.avr;
    int low = !(value & 1) && (avr->data[A_DDRB] & 1);
    if (low == E.mpu.cs_low) return;
    if (low) {
        E.spi_prev_mosi_lsb = 0;
        E.spi_prev_miso_lsb = 0;
        E.cs_transactions++;
        E.txn_conflict = !(avr->data[A_PORTG] & (1 << 1));
        mpu_cs(&E.mpu, 1);
        return;
    }
    if (E.txn_conflict) {
        E.bus_conflicts++;
        E.mpu.now_s = sim_s();
        mpu_violate(&E.mpu, MPU_RULE_BARO_CS, -1);
    }
    E.txn_conflict = 0;
    E.mpu.now_s = sim_s();
    uint64_t read0 = E.mpu.samples_read;
    mpu_cs(&E.mpu, 0);
    if (E.mpu.samples_read != read0) {
        if (!E.steady_started) {
            E.steady_started = 1;
            E.steady_cycle0 = avr->cycle;
            E.steady_sleep0 = E.sleep_cycles;
            E.steady_read0 = E.mpu.samples_read;
        }
        if (E.mpu.latched_idx == E.last_drdy_idx && E.last_drdy_cycle) {
            uint64_t lat = avr->cycle - E.last_drdy_cycle;
            E.latency_sum += lat;
            E.latency_n++;
            if (lat > E.latency_max) E.latency_max = lat;
        }
    }
    if (E.mpu.events) handle_mpu_events();
}

// PG1 = MS5611 /CS: going low while the MPU is selected is a bus conflict
static void baro_cs_cb(avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq, (void)param;
    if (!(value & 1) && E.mpu.cs_low) E.txn_conflict = 1;
}

// ---------------------------------------------------------------- flash: bootloader, persistence
static uint32_t flash_size(void) { return (uint32_t)E.avr->flashend + 1; }

// Program an Intel hex file into flash (its own addresses); returns the lowest address written.
static uint32_t load_ihex(const char *path, const char *what) {
    ihex_chunk_p chunks = NULL;
    int n = read_ihex_chunks(path, &chunks);
    if (n <= 0) {
        fprintf(stderr, "apm_emu: cannot read %s %s (Intel hex)\n", what, path);
        exit(2);
    }
    uint32_t lowest = UINT32_MAX;
    for (int i = 0; i < n; i++) {
        if ((uint64_t)chunks[i].baseaddr + chunks[i].size > flash_size()) {
            fprintf(stderr, "apm_emu: %s %s does not fit in flash (0x%X + %u bytes)\n", what, path,
                    chunks[i].baseaddr, chunks[i].size);
            exit(2);
        }
        memcpy(E.avr->flash + chunks[i].baseaddr, chunks[i].data, chunks[i].size);
        if (chunks[i].size && chunks[i].baseaddr < lowest) lowest = chunks[i].baseaddr;
    }
    free_ihex_chunks(chunks);
    return lowest;
}

// Load the persistent flash image (raw, flash-sized); 0 if the file does not exist yet.
static int flash_file_load(void) {
    FILE *f = fopen(E.flash_file, "rb");
    if (!f) {
        if (errno == ENOENT) return 0;
        die("cannot read --flash-file");
    }
    size_t n = fread(E.avr->flash, 1, flash_size(), f);
    int extra = fgetc(f) != EOF;
    fclose(f);
    if (n != flash_size() || extra) {
        fprintf(stderr, "apm_emu: --flash-file %s is not a %u-byte flash image\n", E.flash_file,
                flash_size());
        exit(2);
    }
    return 1;
}

// Write the flash back to --flash-file when it changed since the last write (atomic rename).
static void flash_file_save(int force) {
    if (!E.flash_file || !E.avr) return;
    if (!force && !memcmp(E.flash_saved, E.avr->flash, flash_size())) return;
    char tmp[4200];
    snprintf(tmp, sizeof tmp, "%s.tmp%d", E.flash_file, (int)getpid());
    FILE *f = fopen(tmp, "wb");
    if (!f || fwrite(E.avr->flash, 1, flash_size(), f) != flash_size() || fclose(f) != 0 ||
        rename(tmp, E.flash_file) != 0) {
        fprintf(stderr, "apm_emu: cannot write --flash-file %s: %s\n", E.flash_file,
                strerror(errno));
        unlink(tmp);
        return;
    }
    memcpy(E.flash_saved, E.avr->flash, flash_size());
    E.flash_saves++;
}

// ---------------------------------------------------------------- UART0 <-> pty
static void tx_flush(void) {
    unsigned off = 0;
    while (off < E.txlen) {
        if (!E.connected) {
            E.tx_dropped += E.txlen - off;
            break;
        }
        ssize_t n = write(E.master, E.txbuf + off, E.txlen - off);
        if (n > 0) {
            off += (unsigned)n;
            continue;
        }
        if (n < 0 && errno != EAGAIN && errno != EINTR && errno != EIO) {
            E.tx_dropped += E.txlen - off;
            break;
        }
        // the host is not reading fast enough: back-pressure (the simulation waits)
        struct pollfd pfd = {.fd = E.master, .events = POLLOUT};
        if (poll(&pfd, 1, 100) > 0 && (pfd.revents & POLLHUP)) E.connected = 0;
        if (E.stop_signal) {
            E.tx_dropped += E.txlen - off;
            break;
        }
    }
    E.txlen = 0;
}

static void uart_out_cb(avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq, (void)param;
    E.tx_bytes++;
    if (!E.connected) {
        E.tx_dropped++;
        return;
    }
    E.txbuf[E.txlen++] = (uint8_t)value;
    if (E.txlen == TXBUF_SIZE) tx_flush();
}

static void uart_xon_cb(avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq, (void)value, (void)param;
    E.uart_xoff = 0;
}

static void uart_xoff_cb(avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq, (void)value, (void)param;
    E.uart_xoff = 1;
}

// Host -> AVR: one byte per byte time (wire pace), never into a full receive FIFO.
static avr_cycle_count_t rx_pump(avr_t *avr, avr_cycle_count_t when, void *param) {
    (void)param;
    if (!E.rxq_len) {
        E.rx_pump_running = 0;
        return 0;
    }
    if (!avr_regbit_get(avr, E.uart->rxen)) {
        // receiver off: a real USART loses what arrives on the wire
        E.rx_dropped += E.rxq_len;
        E.rxq_len = 0;
        E.rx_pump_running = 0;
        return 0;
    }
    if (((E.uart->input.write + 1) & (uart_fifo_fifo_size - 1)) != E.uart->input.read) {  // not full
        uint8_t b = E.rxq[E.rxq_head];
        E.rxq_head = (E.rxq_head + 1) % RXQ_SIZE;
        E.rxq_len--;
        E.rx_bytes++;
        avr_raise_irq(E.irq_uart_in, b);
    }
    avr_cycle_count_t per = E.uart->cycles_per_byte ? E.uart->cycles_per_byte : 1389;
    return when + per;
}

static void rx_pump_start(void) {
    if (E.rx_pump_running || !E.rxq_len) return;
    E.rx_pump_running = 1;
    avr_cycle_timer_register(E.avr, 1, rx_pump, NULL);
}

// Host opens and closes of the pty slave. inotify reports every open/close in order, so a close
// immediately followed by a re-open is never missed; without inotify, fall back to POLLHUP on the
// master (present while no one has the slave open).
// Start-up time of the ATmega2560 after a reset with the Arduino Mega fuses (CKSEL full-swing
// crystal, SUT 11: 16K CK + 65 ms; datasheet table 10-5). Held in wall time, because that is
// what the host lives in: a host's open() configures the tty and flushes its input before the
// board has said anything, as with the real board.
#define STARTUP_HOLD_S 0.065

static void host_opened(void) {
    E.connected = 1;
    E.hold_until = wall_now() + STARTUP_HOLD_S;
    if (E.started && E.dtr_reset) E.reset_requested = 1;
}

// Keep the AVR in reset until the start-up time after the last open has passed.
static void startup_hold(void) {
    double left;
    while (!E.stop_signal && (left = E.hold_until - wall_now()) > 0)
        usleep(left > 0.005 ? 5000 : (useconds_t)(left * 1e6) + 1);
}

static void host_open_events(int hup) {
    if (E.ino < 0) {
        if (!E.connected && !hup) {
            host_opened();
        } else if (E.connected && hup) {
            E.connected = 0;
            E.rxq_len = 0;
            flash_file_save(0);
        }
        return;
    }
    char buf[4096] __attribute__((aligned(__alignof__(struct inotify_event))));
    ssize_t n;
    while ((n = read(E.ino, buf, sizeof buf)) > 0) {
        for (char *p = buf; p < buf + n;) {
            struct inotify_event *ev = (struct inotify_event *)p;
            if (ev->mask & IN_OPEN) {
                // DTR: opening the USB port (first opener) resets the ATmega2560
                if (E.opens++ == 0) host_opened();
            }
            if (ev->mask & (IN_CLOSE_WRITE | IN_CLOSE_NOWRITE)) {
                if (E.opens > 0 && --E.opens == 0) {
                    E.connected = 0;
                    E.rxq_len = 0;
                    flash_file_save(0);  // e.g. avrdude has programmed it: persist at once
                }
            }
            p += sizeof(struct inotify_event) + ev->len;
        }
    }
}

static void host_poll(int timeout_ms) {
    struct pollfd pfd = {.fd = E.master, .events = POLLIN};
    double t0 = timeout_ms > 0 ? wall_now() : 0.0;
    int r = poll(&pfd, 1, timeout_ms);
    if (r < 0) return;
    if (timeout_ms > 0 && !(pfd.revents & POLLIN) && (pfd.revents & POLLHUP)) {
        // no one has the port open (the master reports POLLHUP at once): still pace
        double left = timeout_ms * 1e-3 - (wall_now() - t0);
        if (left > 0) usleep((useconds_t)(left * 1e6));
    }
    host_open_events((pfd.revents & POLLHUP) != 0);
    if (E.connected && (pfd.revents & POLLIN)) {
        uint8_t buf[1024];
        unsigned space = RXQ_SIZE - E.rxq_len;
        if (space > sizeof buf) space = sizeof buf;
        ssize_t n = space ? read(E.master, buf, space) : 0;
        for (ssize_t i = 0; i < n; i++) E.rxq[(E.rxq_head + E.rxq_len++) % RXQ_SIZE] = buf[i];
        if (n > 0) rx_pump_start();
    }
}

// Every POLL_PERIOD_US of simulated time: host I/O, real-time pacing, stop conditions.
static avr_cycle_count_t poll_tick(avr_t *avr, avr_cycle_count_t when, void *param) {
    (void)param;
    tx_flush();
    int timeout = 0;
    if (E.realtime) {
        double ahead = sim_s() - (wall_now() - E.wall_start);
        if (ahead > 0.001) timeout = (int)(ahead * 1000.0);
    }
    if (E.boot && avr->pc >= E.boot_start) {
        // the bootloader's ~0.8 s wait for avrdude is a busy loop: run it in real time, as on
        // the board, so that a host that opens the port (DTR reset) has the window it expects
        if (!E.in_boot) {
            E.in_boot = 1;
            E.boot_entries++;
            E.boot_wall0 = wall_now();
            E.boot_sim0 = sim_s();
        }
        double ahead = (sim_s() - E.boot_sim0) - (wall_now() - E.boot_wall0);
        if (ahead > 0.001 && (int)(ahead * 1000.0) > timeout) timeout = (int)(ahead * 1000.0);
    } else {
        E.in_boot = 0;
    }
    host_poll(timeout);
    if (E.seconds > 0 && sim_s() >= E.seconds && !E.done) {
        E.done = 1;
        E.stop_reason = "seconds reached";
    }
    if (!E.stim.fp && E.seconds <= 0) {
        // no stimulus and no --seconds: run until stopped
    } else if (E.stim.fp && E.seconds <= 0 && E.sample_next_exact < 0) {
        // sensor asleep: still end when the stimulus time is over
        mpu_truth_t t;
        if (!stim_at(&E.stim, sim_s(), &t)) {
            E.done = 1;
            E.stop_reason = "stimulus ended";
        }
    }
    if (E.stop_signal && !E.done) {
        E.done = 1;
        E.stop_reason = "signal";
    }
    return when + avr_usec_to_cycles(avr, POLL_PERIOD_US);
}

// ---------------------------------------------------------------- AVR glue
static void sleep_cb(avr_t *avr, avr_cycle_count_t how_long) {
    (void)avr;
    E.sleep_cycles += how_long + 1;  // the core adds 1 + how_long to the cycle counter
}

static void after_reset(int power_on) {
    avr_t *avr = E.avr;
    uint32_t flags = 0;
    avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~(uint32_t)(AVR_UART_FLAG_STDIO | AVR_UART_FLAG_POLL_SLEEP);
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    avr_extint_set_strict_lvl_trig(avr, 6, 0);
    // MCUSR: power-on at start, external reset (DTR) afterwards
    avr->data[A_MCUSR] = power_on ? 0x01 : 0x02;
    // avr_reset() cleared all cycle timers: re-arm ours
    avr_cycle_timer_register_usec(avr, POLL_PERIOD_US, poll_tick, NULL);
    if (E.sample_next_exact >= 0) sample_clock_schedule();
    if (E.int_asserted && !(E.mpu.reg[MPU_INT_PIN_CFG] & MPU_PIN_LATCH_INT_EN)) {
        E.int_asserted = 0;
    }
    drive_int();
    E.rx_pump_running = 0;
    rx_pump_start();
    // the MPU sees /CS go high as PB0 becomes an input again
    if (E.mpu.cs_low) {
        if (E.txn_conflict) E.bus_conflicts++;
        E.txn_conflict = 0;
        mpu_cs(&E.mpu, 0);
    }
}

static void do_reset(void) {
    E.reset_requested = 0;
    E.avr_resets++;
    tx_flush();
    avr_reset(E.avr);
    after_reset(0);
    startup_hold();
}

// Before closing the master (which hangs the slave up: what the host has not read yet is lost),
// wait until the host has read every byte, as long as it has the port open and keeps reading.
// Bytes written to the master are handed to the slave's line discipline by a kernel worker: on a
// loaded machine they can sit in that flip buffer for a while, invisible to FIONREAD. poll() on a
// slave fd runs the pending hand-over first (n_tty_poll -> tty_buffer_flush_work), so "FIONREAD
// is 0 right after a poll" means the host really has everything. No wall-clock guess: the only
// time limit is for a host that stops reading (DRAIN_STALL_S without progress).
#define DRAIN_STALL_S 10.0

static void drain_to_host(void) {
    if (!E.connected || E.stop_signal) return;  // SIGTERM: the host said it is done
    int fd = open(E.pty_name, O_RDONLY | O_NOCTTY | O_NONBLOCK);
    if (fd < 0) return;
    host_open_events(0);  // our own open is one of E.opens from here on
    double last_progress = wall_now();
    int prev = -1;
    for (;;) {
        host_open_events(0);
        if (E.ino >= 0 && E.opens < 2) break;  // the host closed the port: nothing to deliver
        if (E.stop_signal) break;
        struct pollfd pfd = {.fd = fd, .events = POLLIN};
        poll(&pfd, 1, 0);  // hands pending flip-buffer bytes to the line discipline
        int queued = 0;
        if (ioctl(fd, FIONREAD, &queued) < 0 || queued == 0) break;
        if (queued != prev) last_progress = wall_now();
        prev = queued;
        if (wall_now() - last_progress > DRAIN_STALL_S) break;  // the host stopped reading
        usleep(1000);
    }
    close(fd);
}

static void on_signal(int sig) {
    (void)sig;
    E.stop_signal = 1;
}

static void usage(FILE *f) {
    fprintf(f,
            "usage: apm_emu --elf FW.elf|--hex FW.hex [options]\n"
            "       apm_emu --boot [--flash-file FLASH.bin] [--elf|--hex APP] [options]\n"
            "  --hex FILE            application from an Intel hex file instead of --elf\n"
            "  --boot                stk500v2 bootloader in the boot section, reset vector 0x3E000\n"
            "  --bootloader FILE     ... from this hex (implies --boot; default Debian's\n"
            "                        arduino-core-avr stk500boot_v2_mega2560.hex)\n"
            "  --flash-file FILE     persistent flash image (raw, 256 KiB): loaded at start if it\n"
            "                        exists, written back when the host closes the port after a\n"
            "                        change (avrdude) and at exit. With --elf/--hex the application\n"
            "                        is programmed over it at start\n"
            "  --stimulus FILE|-     truth stream (README.md); default: at rest, Z up, 25 degC\n"
            "  --seconds N           stop after N simulated seconds (default: stimulus end)\n"
            "  --realtime            pace simulated time to the wall clock (default: fast)\n"
            "  --reglog FILE         CSV of every MPU register access\n"
            "  --samplelog FILE      CSV of every produced sample (counts, whether read)\n"
            "  --fault absent|stuck-miso|no-drdy|marginal-bus   inject a fault: marginal-bus =\n"
            "                        above 1 MHz SCLK every MISO byte arrives one bit late\n"
            "  --fault-at S          ... from simulated second S on (default 0)\n"
            "  --pty-file FILE       also write the pty path to FILE\n"
            "  --summary-file FILE   also write the exit summary (JSON) to FILE\n"
            "  --no-wait             start at once (default: hold the CPU until the pty is opened)\n"
            "  --no-dtr-reset        do not reset the AVR when the pty is (re)opened\n"
            "  --noise-accel SIGMA   white noise, m/s^2 (default 0)\n"
            "  --noise-gyro SIGMA    white noise, deg/s (default 0)\n"
            "  --seed S              noise seed\n"
            "  --clock-ppm PPM       MPU sample clock error vs the AVR crystal\n"
            "  --dmp-packet N        DMP stub FIFO packet size (default 42)\n"
            "  --dmp-image NAME      motionapps20|emd6: check the DMP load sequence against that\n"
            "                        image's description (firmware/src/dmp_descriptions.h), its packet size\n"
            "                        for the stub packets\n"
            "  --product-id N        what PRODUCT_ID (0x0C) reads (default 0x58 = rev D8; 0x54/0x55\n"
            "                        = C4/C5: half the accelerometer LSB/g)\n"
            "  --self-test pass|fail the part's self-test response (default pass: within a few %%\n"
            "                        of its factory trim; fail: accel Y +35 %%, gyro Z -45 %%)\n"
            "  --spi-fixed-timing    keep simavr's 100 us per SPI byte\n"
            "  --quiet               no summary on stdout\n"
            "  --profile FILE        CSV of CPU cycles spent per flash address (awake only)\n");
}

// "rules": {"NAME": count, ...}, "rules_broken": ["NAME (ref): text; first at t s, reg 0xRR", ...]
static void write_rules(FILE *f) {
    fprintf(f, "\"rules\": {");
    for (int i = 0; i < MPU_RULE_COUNT; i++)
        fprintf(f, "%s\"%s\": %llu", i ? ", " : "", MPU_RULE_NAME[i],
                (unsigned long long)E.mpu.rule_count[i]);
    fprintf(f, "}, \"rules_broken\": [");
    int n = 0;
    for (int i = 0; i < MPU_RULE_COUNT; i++) {
        if (!E.mpu.rule_count[i]) continue;
        fprintf(f, "%s\"%s (%s): %s; first at %.6f s", n++ ? ", " : "", MPU_RULE_NAME[i],
                MPU_RULE_REF[i], MPU_RULE_TEXT[i], E.mpu.rule_first_t[i]);
        if (E.mpu.rule_first_reg[i] >= 0) fprintf(f, ", register 0x%02X", E.mpu.rule_first_reg[i]);
        fprintf(f, "\"");
    }
    fprintf(f, "], \"dmp_image\": \"%s\", \"dmp_running\": %d, \"dmp_problem\": \"%s\", ",
            E.dmp_desc ? E.dmp_desc->name : "", E.mpu.dmp_running, E.mpu.dmp_problem);
}

static void write_summary(FILE *f, double wall) {
    double sim = sim_s();
    uint64_t busy = (E.avr->cycle - E.start_cycle) - E.sleep_cycles;
    uint64_t samples_read = E.mpu.samples_read;
    double busy_per_sample = samples_read ? (double)busy / (double)samples_read : 0.0;
    double steady = 0.0, steady_load = 0.0;
    if (E.steady_started && E.mpu.samples_read > E.steady_read0) {
        uint64_t cyc = E.avr->cycle - E.steady_cycle0;
        uint64_t b = cyc - (E.sleep_cycles - E.steady_sleep0);
        steady = (double)b / (double)(E.mpu.samples_read - E.steady_read0);
        steady_load = cyc ? (double)b / (double)cyc : 0.0;
    }
    const uint8_t *r = E.mpu.reg;
    fputc('{', f);
    write_rules(f);
    fprintf(f,
            "\"sim_seconds\": %.6f, \"wall_seconds\": %.3f, \"speed\": %.2f, "
            "\"stop_reason\": \"%s\", \"avr_state\": %d, \"pty\": \"%s\", "
            "\"fault\": \"%s\", \"spi_violations\": %llu, \"first_violation_reg\": %d, "
            "\"first_violation_t\": %.6f, \"bus_conflicts\": %llu, "
            "\"samples_produced\": %llu, \"samples_read\": %llu, \"drdy_pulses\": %llu, "
            "\"fifo_overflows\": %llu, \"spi_bytes\": %llu, \"reg_accesses\": %llu, "
            "\"cs_transactions\": %llu, "
            "\"avr_resets\": %llu, \"mpu_resets\": %llu, "
            "\"busy_cycles\": %llu, \"sleep_cycles\": %llu, \"busy_cycles_per_sample\": %.1f, "
            "\"steady_busy_cycles_per_sample\": %.1f, \"steady_cpu_load\": %.5f, "
            "\"drdy_to_read_cycles_mean\": %.1f, \"drdy_to_read_cycles_max\": %llu, "
            "\"uart_tx_bytes\": %llu, \"uart_tx_dropped\": %llu, \"uart_rx_bytes\": %llu, "
            "\"uart_rx_dropped\": %llu, \"spi_timing\": \"%s\", \"stimulus_records\": %lu, "
            "\"boot\": %d, \"boot_entries\": %llu, \"flash_saves\": %llu, "
            "\"product_id\": %u, \"self_test\": \"%s\", \"garbled_bytes\": %llu, "
            "\"regs\": {\"PWR_MGMT_1\": %d, \"SMPLRT_DIV\": %d, \"CONFIG\": %d, "
            "\"GYRO_CONFIG\": %d, \"ACCEL_CONFIG\": %d, \"INT_PIN_CFG\": %d, \"INT_ENABLE\": %d, "
            "\"USER_CTRL\": %d, \"FIFO_EN\": %d, \"PWR_MGMT_2\": %d}}\n",
            sim, wall, wall > 0 ? sim / wall : 0.0, E.stop_reason ? E.stop_reason : "",
            E.avr->state, E.pty_name, FAULT_NAMES[E.fault],
            (unsigned long long)E.spi_violations, E.spi_violations ? E.first_violation_reg : -1,
            E.first_violation_t, (unsigned long long)E.bus_conflicts,
            (unsigned long long)E.mpu.produced, (unsigned long long)samples_read,
            (unsigned long long)E.drdy_pulses, (unsigned long long)E.mpu.fifo_overflows,
            (unsigned long long)E.spi_bytes, (unsigned long long)E.reg_accesses,
            (unsigned long long)E.cs_transactions,
            (unsigned long long)E.avr_resets, (unsigned long long)E.mpu_resets,
            (unsigned long long)busy, (unsigned long long)E.sleep_cycles, busy_per_sample, steady,
            steady_load, E.latency_n ? (double)E.latency_sum / (double)E.latency_n : 0.0,
            (unsigned long long)E.latency_max, (unsigned long long)E.tx_bytes,
            (unsigned long long)E.tx_dropped, (unsigned long long)E.rx_bytes,
            (unsigned long long)E.rx_dropped, E.spi_fixed_timing ? "fixed-100us" : "8x-divider",
            E.stim.records, E.boot, (unsigned long long)E.boot_entries,
            (unsigned long long)E.flash_saves, E.product_id, E.self_test_fail ? "fail" : "pass",
            (unsigned long long)E.garbled_bytes, r[MPU_PWR_MGMT_1], r[MPU_SMPLRT_DIV], r[MPU_CONFIG],
            r[MPU_GYRO_CONFIG], r[MPU_ACCEL_CONFIG], r[MPU_INT_PIN_CFG], r[MPU_INT_ENABLE],
            r[MPU_USER_CTRL], r[MPU_FIFO_EN], r[MPU_PWR_MGMT_2]);
}

int main(int argc, char **argv) {
    E.wait_open = 1;
    E.dtr_reset = 1;
    E.seed = 1;
    E.dmp_packet = 42;
    E.product_id = MPU_PRODUCT_ID_DEFAULT;
    E.sample_next_exact = -1;
    enum {
        O_ELF = 256, O_STIM, O_SECONDS, O_REALTIME, O_REGLOG, O_SAMPLELOG, O_FAULT, O_FAULT_AT,
        O_PTYFILE, O_SUMMARY, O_NOWAIT, O_NODTR, O_NACC, O_NGYR, O_SEED, O_PPM, O_DMP, O_DMPIMG, O_PRODUCT, O_SELFTEST, O_SPIFIX,
        O_QUIET, O_HELP, O_PROFILE, O_HEX, O_BOOT, O_BOOTLOADER, O_FLASHFILE
    };
    static const struct option opts[] = {
        {"elf", 1, 0, O_ELF}, {"stimulus", 1, 0, O_STIM}, {"seconds", 1, 0, O_SECONDS},
        {"realtime", 0, 0, O_REALTIME}, {"reglog", 1, 0, O_REGLOG},
        {"samplelog", 1, 0, O_SAMPLELOG}, {"fault", 1, 0, O_FAULT}, {"fault-at", 1, 0, O_FAULT_AT},
        {"pty-file", 1, 0, O_PTYFILE}, {"summary-file", 1, 0, O_SUMMARY},
        {"no-wait", 0, 0, O_NOWAIT}, {"no-dtr-reset", 0, 0, O_NODTR},
        {"noise-accel", 1, 0, O_NACC}, {"noise-gyro", 1, 0, O_NGYR}, {"seed", 1, 0, O_SEED},
        {"clock-ppm", 1, 0, O_PPM}, {"dmp-packet", 1, 0, O_DMP},
        {"dmp-image", 1, 0, O_DMPIMG}, {"product-id", 1, 0, O_PRODUCT},
        {"self-test", 1, 0, O_SELFTEST},
        {"spi-fixed-timing", 0, 0, O_SPIFIX}, {"quiet", 0, 0, O_QUIET}, {"help", 0, 0, O_HELP}, {"profile", 1, 0, O_PROFILE},
        {"hex", 1, 0, O_HEX}, {"boot", 0, 0, O_BOOT}, {"bootloader", 1, 0, O_BOOTLOADER},
        {"flash-file", 1, 0, O_FLASHFILE},
        {0, 0, 0, 0}};
    int c;
    while ((c = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        switch (c) {
            case O_ELF: E.elf = optarg; break;
            case O_STIM: E.stimulus = optarg; break;
            case O_SECONDS: E.seconds = atof(optarg); break;
            case O_REALTIME: E.realtime = 1; break;
            case O_REGLOG: E.reglog_path = optarg; break;
            case O_SAMPLELOG: E.samplelog_path = optarg; break;
            case O_FAULT:
                if (!strcmp(optarg, "absent")) E.fault = FAULT_ABSENT;
                else if (!strcmp(optarg, "stuck-miso")) E.fault = FAULT_STUCK_MISO;
                else if (!strcmp(optarg, "no-drdy")) E.fault = FAULT_NO_DRDY;
                else if (!strcmp(optarg, "marginal-bus")) E.fault = FAULT_MARGINAL_BUS;
                else if (!strcmp(optarg, "none")) E.fault = FAULT_NONE;
                else die("--fault: absent, stuck-miso, no-drdy, marginal-bus or none");
                break;
            case O_FAULT_AT: E.fault_at = atof(optarg); break;
            case O_PTYFILE: E.pty_file = optarg; break;
            case O_SUMMARY: E.summary_file = optarg; break;
            case O_NOWAIT: E.wait_open = 0; break;
            case O_NODTR: E.dtr_reset = 0; break;
            case O_NACC: E.noise_accel = atof(optarg); break;
            case O_NGYR: E.noise_gyro = atof(optarg); break;
            case O_SEED: E.seed = strtoull(optarg, NULL, 0); break;
            case O_PPM: E.clock_ppm = atof(optarg); break;
            case O_DMP: E.dmp_packet = (unsigned)atoi(optarg); break;
            case O_PRODUCT: {
                char *end;
                unsigned long v = strtoul(optarg, &end, 0);
                if (!*optarg || *end || v > 0xFF) die("--product-id: a byte, e.g. 0x55 (rev C5)");
                E.product_id = (unsigned)v;
                break;
            }
            case O_SELFTEST:
                if (!strcmp(optarg, "pass")) E.self_test_fail = 0;
                else if (!strcmp(optarg, "fail")) E.self_test_fail = 1;
                else die("--self-test: pass or fail");
                break;
            case O_DMPIMG:
                for (unsigned i = 0; i < sizeof DMP_IMAGES / sizeof DMP_IMAGES[0]; i++)
                    if (!strcmp(optarg, DMP_IMAGES[i].name)) E.dmp_desc = &DMP_IMAGES[i];
                if (!E.dmp_desc) die("--dmp-image: motionapps20 or emd6");
                break;
            case O_SPIFIX: E.spi_fixed_timing = 1; break;
            case O_QUIET: E.quiet = 1; break;
            case O_HELP: usage(stdout); return 0;
            case O_PROFILE: E.profile_path = optarg; break;
            case O_HEX: E.hex = optarg; break;
            case O_BOOT: E.boot = 1; break;
            case O_BOOTLOADER: E.boot = 1; E.bootloader = optarg; break;
            case O_FLASHFILE: E.flash_file = optarg; break;
            default: usage(stderr); return 2;
        }
    }
    if (E.elf && E.hex) die("--elf and --hex: give one application");
    if (!E.elf && !E.hex && !E.boot && !E.flash_file) {
        usage(stderr);
        return 2;
    }
    if (E.boot && !E.bootloader) E.bootloader = DEFAULT_BOOTLOADER;
    E.rng = E.seed;

    if (E.reglog_path) {
        if (!(E.reglog = fopen(E.reglog_path, "w"))) die("cannot write --reglog file");
        setvbuf(E.reglog, NULL, _IOFBF, 1 << 16);
        fprintf(E.reglog, "t_us,op,reg,value,spi_hz,violation\n");
    }
    if (E.samplelog_path) {
        if (!(E.samplelog = fopen(E.samplelog_path, "w"))) die("cannot write --samplelog file");
        setvbuf(E.samplelog, NULL, _IOFBF, 1 << 16);
        fprintf(E.samplelog, "idx,t_us,ax,ay,az,temp,gx,gy,gz,read\n");
    }

    // simavr's loader and init print to stdout: send that to stderr, so that our stdout protocol
    // stays clean (first line "PTY /dev/pts/N", last line "SUMMARY {json}")
    fflush(stdout);
    int saved_stdout = dup(1);
    dup2(2, 1);
    elf_firmware_t fw;
    memset(&fw, 0, sizeof fw);
    if (E.elf && elf_read_firmware(E.elf, &fw) != 0) die("cannot read the firmware ELF");
    if (!fw.mmcu[0]) strcpy(fw.mmcu, "atmega2560");
    if (!fw.frequency) fw.frequency = 16000000;
    avr_t *avr = avr_make_mcu_by_name(fw.mmcu);
    if (!avr) die("unknown MCU in the ELF");
    avr_init(avr);
    E.avr = avr;
    // Flash, as on the chip: the persistent image (if any), then an application programmed over
    // it (--elf/--hex, after erasing it, like an ISP programmer), then the bootloader.
    int flash_loaded = 0;
    if (E.flash_file) {
        flash_loaded = flash_file_load();
        if (!(E.flash_saved = malloc(flash_size()))) die("out of memory");
        memcpy(E.flash_saved, avr->flash, flash_size());
    }
    if (E.elf || E.hex) memset(avr->flash, 0xFF, flash_size());
    if (E.elf) avr_load_firmware(avr, &fw);
    if (E.hex) load_ihex(E.hex, "application");
    if (E.boot) {
        E.boot_start = load_ihex(E.bootloader, "bootloader");
        avr->reset_pc = avr->pc = E.boot_start;  // BOOTRST fuse programmed (simavr has none)
        avr->codeend = avr->flashend;
    } else if (!E.elf) {
        avr->codeend = avr->flashend;
    }
    flash_file_save(!flash_loaded);  // a new file, or what was programmed over it
    fflush(stdout);
    fputc('\n', stderr);
    dup2(saved_stdout, 1);
    close(saved_stdout);
    avr->frequency = fw.frequency;
    avr->log = 0;
    avr->sleep = sleep_cb;  // never sleep in real time: pacing (if any) is done in poll_tick
    E.freq = avr->frequency;

    for (avr_io_t *io = avr->io_port; io; io = io->next) {
        if (!strcmp(io->kind, "spi") && !E.spi) E.spi = (avr_spi_t *)io;
        if (!strcmp(io->kind, "uart") && ((avr_uart_t *)io)->name == '0') E.uart = (avr_uart_t *)io;
    }
    if (!E.spi || !E.uart) die("no SPI or UART0 in this MCU model");
    // SPI timing
    avr->io[AVR_DATA_TO_IO(E.spi->r_spdr)].w.c = spdr_write;
    avr->io[AVR_DATA_TO_IO(E.spi->r_spdr)].w.param = E.spi;

    avr_irq_t *spi_out = avr_io_getirq(avr, AVR_IOCTL_SPI_GETIRQ(0), SPI_IRQ_OUTPUT);
    E.irq_spi_in = avr_io_getirq(avr, AVR_IOCTL_SPI_GETIRQ(0), SPI_IRQ_INPUT);
    if (!spi_out) {
        spi_out = avr_io_getirq(avr, AVR_IOCTL_SPI_GETIRQ('0'), SPI_IRQ_OUTPUT);
        E.irq_spi_in = avr_io_getirq(avr, AVR_IOCTL_SPI_GETIRQ('0'), SPI_IRQ_INPUT);
    }
    if (!spi_out || !E.irq_spi_in) die("SPI irqs not found");
    avr_irq_register_notify(spi_out, spi_out_cb, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('B'), 0), cs_cb, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('G'), 1), baro_cs_cb, NULL);
    E.irq_int = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('E'), 6);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                            uart_out_cb, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON),
                            uart_xon_cb, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF),
                            uart_xoff_cb, NULL);
    E.irq_uart_in = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);

    if (E.dmp_desc) E.dmp_packet = E.dmp_desc->packet_size;
    mpu_power_on(&E.mpu, E.dmp_packet, (uint8_t)E.product_id);
    mpu_self_test(&E.mpu, E.self_test_fail);
    E.mpu.dmp_desc = E.dmp_desc;
    E.mpu.retire = on_retire;
    E.mpu.power_on_until = MPU_POWER_ON_S - STARTUP_HOLD_S;  // power-on reset, in emulated time
    E.filt_last_t = -1.0;

    // pseudo-terminal
    int slave;
    if (openpty(&E.master, &slave, E.pty_name, NULL, NULL) < 0) die("openpty failed");
    struct termios tio;
    tcgetattr(slave, &tio);
    cfmakeraw(&tio);
    tcsetattr(slave, TCSANOW, &tio);
    close(slave);  // POLLHUP on the master until the host opens the slave
    fcntl(E.master, F_SETFL, fcntl(E.master, F_GETFL) | O_NONBLOCK);
    E.ino = inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
    if (E.ino >= 0 && inotify_add_watch(E.ino, E.pty_name, IN_OPEN | IN_CLOSE) < 0) {
        close(E.ino);
        E.ino = -1;
    }
    printf("PTY %s\n", E.pty_name);
    fflush(stdout);
    if (E.pty_file) {
        FILE *f = fopen(E.pty_file, "w");
        if (!f) die("cannot write --pty-file");
        fprintf(f, "%s\n", E.pty_name);
        fclose(f);
    }

    // after "PTY": a stimulus on a pipe may only be written once the caller has seen the pty
    if (stim_open(&E.stim, E.stimulus) < 0) die(E.stim.error);

    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);

    if (E.wait_open) {
        // the board is "plugged in" when the host opens the port: hold the CPU until then
        while (!E.stop_signal) {
            struct pollfd pfd = {.fd = E.master, .events = POLLIN};
            poll(&pfd, 1, 0);
            host_open_events((pfd.revents & POLLHUP) != 0);
            if (E.connected) break;
            usleep(1000);
        }
    } else {
        struct pollfd pfd = {.fd = E.master, .events = POLLIN};
        poll(&pfd, 1, 0);
        host_open_events((pfd.revents & POLLHUP) != 0);
    }
    if (E.wait_open) startup_hold();
    E.started = 1;

    E.start_cycle = avr->cycle;
    E.wall_start = wall_now();
    after_reset(1);

    uint64_t *prof = NULL;
    if (E.profile_path) prof = calloc((avr->flashend + 1) / 2, sizeof *prof);
    while (!E.done) {
        if (prof && avr->state == cpu_Running) {
            avr_flashaddr_t pc = avr->pc;
            avr_cycle_count_t c0 = avr->cycle;
            uint64_t s0 = E.sleep_cycles;
            int state = avr_run(avr);
            if (pc / 2 <= avr->flashend / 2) prof[pc / 2] += avr->cycle - c0 - (E.sleep_cycles - s0);
            if (state == cpu_Done || state == cpu_Crashed) {
                E.stop_reason = state == cpu_Crashed ? "avr crashed" : "avr done";
                break;
            }
            if (E.reset_requested) do_reset();
            continue;
        }
        int state = avr_run(avr);
        if (state == cpu_Done || state == cpu_Crashed) {
            E.stop_reason = state == cpu_Crashed ? "avr crashed" : "avr done (sleep with interrupts off?)";
            break;
        }
        if (E.reset_requested) do_reset();
    }
    tx_flush();
    double wall = wall_now() - E.wall_start;
    drain_to_host();
    if (prof) {
        FILE *pf = fopen(E.profile_path, "w");
        if (pf) {
            fprintf(pf, "byte_addr,cycles\n");
            for (uint32_t i = 0; i <= avr->flashend / 2; i++)
                if (prof[i]) fprintf(pf, "0x%05X,%llu\n", i * 2, (unsigned long long)prof[i]);
            fclose(pf);
        }
        free(prof);
    }
    flash_file_save(0);
    mpu_finish(&E.mpu);
    if (E.reglog) fclose(E.reglog);
    if (E.samplelog) fclose(E.samplelog);
    stim_close(&E.stim);
    if (!E.quiet) {
        printf("SUMMARY ");
        write_summary(stdout, wall);
        fflush(stdout);
    }
    if (E.summary_file) {
        FILE *f = fopen(E.summary_file, "w");
        if (f) {
            write_summary(f, wall);
            fclose(f);
        }
    }
    close(E.master);
    return 0;
}
