// MPU-6000 register-level model. See mpu6000.h and README.md.
#include "mpu6000.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define G0 9.80665
static const double ACCEL_LSB_PER_G[4] = {16384.0, 8192.0, 4096.0, 2048.0};
static const double GYRO_LSB_PER_DPS[4] = {131.0, 65.5, 32.8, 16.4};  // datasheet p.12

const char *const MPU_RULE_NAME[MPU_RULE_COUNT] = {
    "SPI_CLOCK", "SPI_MODE", "SPI_BIT_ORDER", "BARO_CS", "DRDY_EDGE", "RESET_WAIT",
    "SIGNAL_PATH_RESET", "SIGNAL_PATH_WAIT", "GYRO_STARTUP", "I2C_IF_DIS", "READ_ONLY",
    "RESERVED", "DMP_LOAD", "POWER_ON",
};
const char *const MPU_RULE_REF[MPU_RULE_COUNT] = {
    "PS p.15", "PS p.37", "PS p.37", "APM 2.6 schematic", "RM p.26", "RM p.41", "RM p.41",
    "RM p.41", "PS p.12", "RM p.38", "RM p.6-8", "RM p.6-8", "firmware/src/dmp_descriptions.h",
    "RM p.41, PS p.14",
};
const char *const MPU_RULE_TEXT[MPU_RULE_COUNT] = {
    "configuration registers are specified up to 1 MHz SPI clock (20 MHz only for sensor and "
    "interrupt registers)",
    "the MPU-6000 latches data on the rising SCLK edge and shifts on the falling one: SPI mode 0 "
    "or 3 (CPOL = CPHA); another mode shifts every byte by one bit",
    "SPI data is MSB first: with DORD = 1 every byte is bit-reversed",
    "the MS5611 shares the bus: its /CS (PG1) must be high while the MPU-6000 is selected",
    "with LATCH_INT_EN = 0 data ready is a 50 us pulse: INT6 must sense its leading edge, else "
    "every time stamp is 50 us late (or taken twice)",
    "after DEVICE_RESET the part is in reset for 100 ms: registers are unreachable (reads 0x00, "
    "writes lost)",
    "in SPI mode DEVICE_RESET must be followed by SIGNAL_PATH_RESET (gyro, accel, temp) before "
    "sensor data is valid",
    "after SIGNAL_PATH_RESET wait 100 ms before touching the part",
    "gyroscope start-up time is 30 ms after wake-up: earlier samples are not valid",
    "in SPI mode set USER_CTRL.I2C_IF_DIS before reading data (the I2C slave otherwise sees the "
    "SPI traffic)",
    "the register is read-only: a write is lost",
    "reserved register: writes have undefined effects",
    "the DMP runs its image only when the whole image was written and read back, the FIFO-rate "
    "update written, DMP_CFG_1/2 hold its start address and FS_SEL, SMPLRT_DIV and DLPF_CFG are "
    "what the image assumes, before DMP_EN",
    "after power-on the part is in reset for 100 ms from VDD valid: registers are unreachable "
    "(reads 0x00, writes lost); the AVR starts 65 ms after power-on, so wait >= 35 ms more",
};

// RM p.13, DLPF_CFG 0..6; 7 is reserved (modelled as 0: no filter, 8 kHz)
const mpu_dlpf_spec_t MPU_DLPF[8] = {
    {260.0, 0.0, 256.0, 0.98}, {184.0, 2.0, 188.0, 1.9}, {94.0, 3.0, 98.0, 2.8},
    {44.0, 4.9, 42.0, 4.8},    {21.0, 8.5, 20.0, 8.3},   {10.0, 13.8, 10.0, 13.4},
    {5.0, 19.0, 5.0, 18.6},    {0.0, 0.0, 0.0, 0.0},
};

// b(zeta): -3 dB frequency / natural frequency of H = w0^2 / (s^2 + 2 zeta w0 s + w0^2)
static double bw_ratio(double z) {
    double a = 1.0 - 2.0 * z * z;
    return sqrt(a + sqrt(a * a + 1.0));
}

void mpu_filter_design(mpu_filter_t *f, double bw, double delay_s, double fs) {
    double T = 1.0 / fs;
    f->b0 = 1.0;
    f->a1 = f->a2 = 0.0;
    f->delay_s = delay_s > 0 ? delay_s : 0.0;
    if (bw <= 0 || delay_s <= 0) return;
    double P = bw * delay_s;  // bandwidth x delay: 1/(2 pi) for a first-order low-pass
    if (P >= 1.0 / (2.0 * M_PI)) {
        // first order, its pole placed so that the discrete -3 dB point is exactly bw
        double c = cos(2.0 * M_PI * bw * T);
        double p = (2.0 - c) - sqrt((2.0 - c) * (2.0 - c) - 1.0);
        f->a1 = -p;
    } else {
        // less delay than a first-order low-pass of that bandwidth has (DLPF_CFG 5, 6): an
        // underdamped second order, zeta from bw * delay = zeta * b(zeta) / pi (increasing on
        // 0 < zeta <= 1/sqrt(2)), poles matched to the continuous ones
        double lo = 1e-4, hi = M_SQRT1_2;
        for (int i = 0; i < 60; i++) {
            double z = 0.5 * (lo + hi);
            if (z * bw_ratio(z) / M_PI < P) lo = z; else hi = z;
        }
        double z = 0.5 * (lo + hi), w0 = 2.0 * M_PI * bw / bw_ratio(z);
        double r = exp(-z * w0 * T), th = w0 * T * sqrt(1.0 - z * z);
        f->a1 = -2.0 * r * cos(th);
        f->a2 = r * r;
    }
    f->b0 = 1.0 + f->a1 + f->a2;
    // the section's own DC group delay, -(a1 + 2 a2) / (1 + a1 + a2) samples; the rest is pure
    double lag = -(f->a1 + 2.0 * f->a2) / f->b0 * T;
    f->delay_s = delay_s - lag > 0 ? delay_s - lag : 0.0;
}

double mpu_filter_group_delay_s(const mpu_filter_t *f, double fs) {
    return f->delay_s - (f->a1 + 2.0 * f->a2) / f->b0 / fs;
}

double mpu_internal_rate_hz(const mpu6000_t *m) {
    unsigned dlpf = m->reg[MPU_CONFIG] & 7;
    return (dlpf == 0 || dlpf == 7) ? 8000.0 : 1000.0;
}

void mpu_filter_reset(mpu6000_t *m) { m->filt_settle = 1; }

static double filter_step(mpu_filter_t *f, int axis, double x, int settle) {
    if (settle) f->y1[axis] = f->y2[axis] = x;
    double y = f->b0 * x - f->a1 * f->y1[axis] - f->a2 * f->y2[axis];
    f->y2[axis] = f->y1[axis];
    f->y1[axis] = y;
    return y;
}

void mpu_dlpf_delays(mpu6000_t *m, double *accel_s, double *gyro_s) {
    double fs = mpu_internal_rate_hz(m);
    int cfg = m->reg[MPU_CONFIG] & 7;
    if (cfg != m->filt_cfg || fs != m->filt_fs) {  // a new design keeps the filters' state
        const mpu_dlpf_spec_t *s = &MPU_DLPF[cfg];
        mpu_filter_t a = m->filt_accel, g = m->filt_gyro;
        mpu_filter_design(&m->filt_accel, s->accel_bw_hz, s->accel_delay_ms * 1e-3, fs);
        mpu_filter_design(&m->filt_gyro, s->gyro_bw_hz, s->gyro_delay_ms * 1e-3, fs);
        memcpy(m->filt_accel.y1, a.y1, sizeof a.y1);
        memcpy(m->filt_accel.y2, a.y2, sizeof a.y2);
        memcpy(m->filt_gyro.y1, g.y1, sizeof g.y1);
        memcpy(m->filt_gyro.y2, g.y2, sizeof g.y2);
        m->filt_cfg = cfg;
        m->filt_fs = fs;
    }
    *accel_s = m->filt_accel.delay_s;
    *gyro_s = m->filt_gyro.delay_s;
}

void mpu_internal_tick(mpu6000_t *m, const mpu_truth_t *a, const mpu_truth_t *g) {
    for (int i = 0; i < 3; i++) {
        uint8_t st = (uint8_t)(0x80 >> i);  // X/Y/Z_ST: bits 7, 6, 5
        double fa = a->f[i] + ((m->reg[MPU_ACCEL_CONFIG] & st) ? m->st_accel_g[i] * G0 : 0.0);
        double wg = g->w[i] + ((m->reg[MPU_GYRO_CONFIG] & st) ? m->st_gyro_dps[i] : 0.0);
        m->filtered[i] = filter_step(&m->filt_accel, i, fa, m->filt_settle);
        m->filtered[3 + i] = filter_step(&m->filt_gyro, i, wg, m->filt_settle);
    }
    m->filt_settle = 0;
}

void mpu_violate(mpu6000_t *m, int rule, int reg) {
    if (rule < 0 || rule >= MPU_RULE_COUNT) return;
    if (!m->rule_count[rule]++) {
        m->rule_first_t[rule] = m->now_s;
        m->rule_first_reg[rule] = reg;
    }
}

// Registers documented in RM-MPU-6000A-00 (or known and used: offsets/self-test 0x00-0x18 incl.
// PRODUCT_ID 0x0C, the DMP memory and configuration ports 0x6D-0x71). Anything else is reserved.
static int reg_reserved(uint8_t r) {
    return (r >= 0x1D && r <= 0x22) || r == 0x39 || r == 0x61 || r == 0x62 || r == 0x69 ||
           r >= 0x76;
}

static int reg_read_only(uint8_t r) {
    return r == MPU_WHO_AM_I || r == MPU_INT_STATUS || r == MPU_PRODUCT_ID ||
           (r >= MPU_ACCEL_XOUT_H && r <= 0x60);  // sensor and external sensor data
}

#define BIT_SET(map, i) ((map)[(i) >> 3] |= (uint8_t)(1u << ((i) & 7)))
#define BIT_GET(map, i) (((map)[(i) >> 3] >> ((i) & 7)) & 1u)

// DMP_EN set: does the chip hold what the described image needs to run? (m->dmp_problem)
static int dmp_load_ok(mpu6000_t *m, int *reg) {
    const dmp_image_desc_t *d = m->dmp_desc;
    char *why = m->dmp_problem;
    size_t n = sizeof m->dmp_problem;
    for (unsigned a = 0; a < d->code_size; a++) {
        if (!BIT_GET(m->dmp_written, a) || !BIT_GET(m->dmp_readback, a)) {
            snprintf(why, n, "%s: DMP memory 0x%04X %s (image is %u bytes)", d->name, a,
                     BIT_GET(m->dmp_written, a) ? "never read back" : "never written",
                     d->code_size);
            *reg = MPU_MEM_R_W;
            return 0;
        }
    }
    unsigned div = DMP_RATE_HZ / d->fifo_rate_hz - 1;
    const uint8_t *rate = &m->dmp_mem[DMP_FIFO_RATE_ADDR];
    if (!BIT_GET(m->dmp_written, DMP_FIFO_RATE_ADDR) || rate[0] != (div >> 8) ||
        rate[1] != (div & 0xFF)) {
        snprintf(why, n, "%s: FIFO-rate update at DMP 0x%04X is %02X %02X, %u Hz needs %02X %02X",
                 d->name, DMP_FIFO_RATE_ADDR, rate[0], rate[1], d->fifo_rate_hz, div >> 8,
                 div & 0xFF);
        *reg = MPU_MEM_R_W;
        return 0;
    }
    unsigned start = (unsigned)m->reg[MPU_DMP_CFG_1] << 8 | m->reg[MPU_DMP_CFG_2];
    if (start != d->start_addr) {
        snprintf(why, n, "%s: start address 0x%04X in DMP_CFG_1/2, the image starts at 0x%04X",
                 d->name, start, d->start_addr);
        *reg = MPU_DMP_CFG_1;
        return 0;
    }
    struct { int reg; unsigned got, want; const char *what; } cfg[] = {
        {MPU_GYRO_CONFIG, (m->reg[MPU_GYRO_CONFIG] >> 3) & 3, d->gyro_fs_sel, "FS_SEL"},
        {MPU_ACCEL_CONFIG, (m->reg[MPU_ACCEL_CONFIG] >> 3) & 3, d->accel_fs_sel, "AFS_SEL"},
        {MPU_SMPLRT_DIV, m->reg[MPU_SMPLRT_DIV], d->smplrt_div, "SMPLRT_DIV"},
        {MPU_CONFIG, m->reg[MPU_CONFIG] & 7u, d->dlpf_cfg, "DLPF_CFG"},
    };
    for (unsigned i = 0; i < sizeof cfg / sizeof cfg[0]; i++) {
        if (cfg[i].got != cfg[i].want) {
            snprintf(why, n, "%s: %s is %u, the image needs %u", d->name, cfg[i].what,
                     cfg[i].got, cfg[i].want);
            *reg = cfg[i].reg;
            return 0;
        }
    }
    why[0] = 0;
    return 1;
}

int mpu_half_accel_sensitivity(uint8_t id) {
    return id == 0x14 || id == 0x15 || id == 0x54 || id == 0x55;
}

static void retire_latched(mpu6000_t *m) {
    if (m->latched_idx && m->retire)
        m->retire(m->retire_ctx, m->latched_idx, m->latched_t, m->latched_counts,
                  m->latched_fully_read ? 1 + m->latched_read_garbled : 0);
    m->latched_idx = 0;
}

void mpu_finish(mpu6000_t *m) { retire_latched(m); }

static void reset_registers(mpu6000_t *m) {
    retire_latched(m);
    memset(m->reg, 0, sizeof m->reg);
    m->reg[MPU_PWR_MGMT_1] = MPU_PWR1_SLEEP;  // 0x40: asleep after power-on / DEVICE_RESET
    m->reg[MPU_WHO_AM_I] = 0x68;
    m->reg[MPU_PRODUCT_ID] = m->product_id;  // undocumented register (ArduPilot's list)
    // factory self-test codes (plausible values; the firmware only reads them for self-test)
    m->reg[0x0D] = 0x4C;
    m->reg[0x0E] = 0x4D;
    m->reg[0x0F] = 0x6A;
    m->reg[0x10] = 0x56;
    m->fifo_rd = m->fifo_count = 0;
    m->latch_pending = 0;
    m->latched_fully_read = 1;
    memset(m->counts, 0, sizeof m->counts);
    m->q[0] = 1.0;
    m->q[1] = m->q[2] = m->q[3] = 0.0;
    mpu_filter_reset(m);
}

void mpu_power_on(mpu6000_t *m, unsigned dmp_packet_size, uint8_t product_id) {
    memset(m, 0, sizeof *m);
    m->product_id = product_id;
    m->dmp_packet_size = dmp_packet_size ? dmp_packet_size : 42;
    reset_registers(m);
    mpu_self_test(m, 0);
}

void mpu_self_test(mpu6000_t *m, int fail) {
    // The factory trim (RM p.10-11) from the 5-bit codes in SELF_TEST_X/Y/Z (XG_TEST bits 4..0,
    // XA_TEST[4:2] bits 7..5) and SELF_TEST_A (XA/YA/ZA_TEST[1:0] in bits 5..4, 3..2, 1..0):
    // gyro 25 * 131 LSB * 1.046^(code - 1) at +-250 deg/s (Y negative), accel 4096 LSB *
    // 0.34 * (0.92 / 0.34)^((code - 1) / 30) at +-8 g; code 0: no trim, no response.
    static const double healthy_accel[3] = {0.021, -0.034, 0.012};
    static const double healthy_gyro[3] = {-0.015, 0.026, -0.022};
    const uint8_t *r = m->reg;
    for (int i = 0; i < 3; i++) {
        unsigned g_code = r[MPU_SELF_TEST_X + i] & 0x1F;
        unsigned a_code = (unsigned)((r[MPU_SELF_TEST_X + i] >> 3) & 0x1C) |
                          ((r[MPU_SELF_TEST_A] >> (4 - 2 * i)) & 0x3);
        double g_ft = g_code ? (i == 1 ? -1.0 : 1.0) * 25.0 * pow(1.046, g_code - 1.0) : 0.0;
        double a_ft = a_code ? 0.34 * pow(0.92 / 0.34, (a_code - 1.0) / 30.0) : 0.0;
        double a_dev = healthy_accel[i], g_dev = healthy_gyro[i];
        if (fail && i == 1) a_dev = 0.35;
        if (fail && i == 2) g_dev = -0.45;
        m->st_accel_g[i] = a_ft * (1.0 + a_dev);  // 4096 LSB at +-8 g = 1 g
        m->st_gyro_dps[i] = g_ft * (1.0 + g_dev); // 131 LSB at +-250 deg/s = 1 deg/s
    }
}

void mpu_device_reset(mpu6000_t *m) {
    // DMP memory is RAM inside the chip: DEVICE_RESET does not clear it in the model either.
    reset_registers(m);
    m->reset_until = m->now_s + MPU_RESET_WAIT_S;
    m->dmp_running = 0;
    m->signal_path_needed = 1;
    m->events |= MPU_EV_CLOCK | MPU_EV_PIN_CFG | MPU_EV_RESET;
}

int mpu_awake(const mpu6000_t *m) { return !(m->reg[MPU_PWR_MGMT_1] & MPU_PWR1_SLEEP); }

unsigned mpu_period_ticks_8k(const mpu6000_t *m) {
    unsigned dlpf = m->reg[MPU_CONFIG] & 7;
    unsigned base = (dlpf == 0 || dlpf == 7) ? 1 : 8;  // gyro output rate 8 kHz or 1 kHz
    return base * (1u + m->reg[MPU_SMPLRT_DIV]);
}

int mpu_is_sensor_reg(uint8_t reg) {
    return reg == MPU_INT_STATUS || (reg >= MPU_ACCEL_XOUT_H && reg <= MPU_GYRO_ZOUT_L) ||
           reg == MPU_FIFO_COUNTH || reg == MPU_FIFO_COUNTL || reg == MPU_FIFO_R_W;
}

static int16_t sat16(double c) {
    c = rint(c);  // round half to even, like numpy.rint in host/sensor.py
    if (c > 32767.0) return 32767;
    if (c < -32768.0) return -32768;
    return (int16_t)c;
}

void mpu_convert(const mpu6000_t *m, const mpu_truth_t *t, int16_t out[7]) {
    unsigned afs = (m->reg[MPU_ACCEL_CONFIG] >> 3) & 3;
    unsigned fs = (m->reg[MPU_GYRO_CONFIG] >> 3) & 3;
    double half = mpu_half_accel_sensitivity(m->product_id) ? 0.5 : 1.0;
    for (int i = 0; i < 3; i++) {
        out[i] = sat16(t->f[i] * (half * ACCEL_LSB_PER_G[afs] / G0));
        out[4 + i] = sat16(t->w[i] * GYRO_LSB_PER_DPS[fs]);
    }
    out[3] = sat16((t->temp - 36.53) * 340.0);
}

static void fifo_push(mpu6000_t *m, uint8_t b) {
    if (m->fifo_count >= MPU_FIFO_SIZE) {
        // full: the oldest byte is lost (RM p.27, FIFO_OFLOW_INT)
        m->fifo_rd = (m->fifo_rd + 1) % MPU_FIFO_SIZE;
        m->fifo_count--;
        m->reg[MPU_INT_STATUS] |= MPU_INT_FIFO_OFLOW;
        m->fifo_overflows++;
    }
    m->fifo[(m->fifo_rd + m->fifo_count) % MPU_FIFO_SIZE] = b;
    m->fifo_count++;
}

static uint8_t fifo_pop(mpu6000_t *m) {
    if (!m->fifo_count) return 0;  // reading an empty FIFO gives undefined data: 0 here
    uint8_t b = m->fifo[m->fifo_rd];
    m->fifo_rd = (m->fifo_rd + 1) % MPU_FIFO_SIZE;
    m->fifo_count--;
    return b;
}

static void put16(uint8_t *p, int16_t v) {
    p[0] = (uint8_t)((uint16_t)v >> 8);
    p[1] = (uint8_t)v;
}

static void put32(uint8_t *p, int32_t v) {
    uint32_t u = (uint32_t)v;
    p[0] = (uint8_t)(u >> 24);
    p[1] = (uint8_t)(u >> 16);
    p[2] = (uint8_t)(u >> 8);
    p[3] = (uint8_t)u;
}

static void latch(mpu6000_t *m) {
    retire_latched(m);
    memcpy(m->latched_counts, m->counts, sizeof m->counts);
    m->latched_t = m->counts_t;
    for (int i = 0; i < 7; i++) put16(&m->reg[MPU_ACCEL_XOUT_H + 2 * i], m->counts[i]);
    m->latched_idx = m->produced;
    m->latched_fully_read = 0;
    m->latched_read_garbled = 0;
    m->latched_early = m->latched_t < m->gyro_valid_from;
    m->latch_pending = 0;
}

static void dmp_integrate(mpu6000_t *m, const mpu_truth_t *t, double dt) {
    // q <- q * exp(0.5 * w * dt), body rates in rad/s
    double wx = t->w[0] * M_PI / 180.0, wy = t->w[1] * M_PI / 180.0, wz = t->w[2] * M_PI / 180.0;
    double n = sqrt(wx * wx + wy * wy + wz * wz);
    double a = 0.5 * n * dt;
    double s = n > 1e-12 ? sin(a) / n : 0.5 * dt;
    double dq[4] = {cos(a), wx * s, wy * s, wz * s};
    double *q = m->q;
    double r[4] = {
        q[0] * dq[0] - q[1] * dq[1] - q[2] * dq[2] - q[3] * dq[3],
        q[0] * dq[1] + q[1] * dq[0] + q[2] * dq[3] - q[3] * dq[2],
        q[0] * dq[2] - q[1] * dq[3] + q[2] * dq[0] + q[3] * dq[1],
        q[0] * dq[3] + q[1] * dq[2] - q[2] * dq[1] + q[3] * dq[0],
    };
    double nn = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]);
    for (int i = 0; i < 4; i++) q[i] = r[i] / nn;
}

void mpu_sample(mpu6000_t *m, const mpu_truth_t *t, double dt_s) {
    mpu_convert(m, t, m->counts);
    m->counts_t = m->now_s;
    m->produced++;
    if (m->cs_low)
        m->latch_pending = 1;  // the serial interface is busy: update when it goes idle
    else
        latch(m);
    m->reg[MPU_INT_STATUS] |= MPU_INT_DATA_RDY;

    uint8_t uc = m->reg[MPU_USER_CTRL];
    if (uc & MPU_UC_FIFO_EN) {
        uint8_t en = m->reg[MPU_FIFO_EN];
        uint8_t b[2];
        if (en & 0x08)  // ACCEL_FIFO_EN
            for (int i = 0; i < 3; i++) {
                put16(b, m->counts[i]);
                fifo_push(m, b[0]);
                fifo_push(m, b[1]);
            }
        if (en & 0x80) {  // TEMP_FIFO_EN
            put16(b, m->counts[3]);
            fifo_push(m, b[0]);
            fifo_push(m, b[1]);
        }
        for (int i = 0; i < 3; i++)
            if (en & (0x40 >> i)) {  // XG, YG, ZG_FIFO_EN
                put16(b, m->counts[4 + i]);
                fifo_push(m, b[0]);
                fifo_push(m, b[1]);
            }
    }
    if ((uc & MPU_UC_DMP_EN) && (m->dmp_running || !m->dmp_desc)) {
        dmp_integrate(m, t, dt_s);
        if (uc & MPU_UC_FIFO_EN) {
            // DMP stub packet (MotionApps-2 layout): quaternion q30 (16 bytes), gyro (3 x 32-bit,
            // counts in the high half), accel (3 x 32-bit, counts in the high half), zero padding.
            uint8_t pkt[64] = {0};
            for (int i = 0; i < 4; i++) put32(pkt + 4 * i, (int32_t)lrint(m->q[i] * 1073741824.0));
            for (int i = 0; i < 3; i++) put16(pkt + 16 + 4 * i, m->counts[4 + i]);
            for (int i = 0; i < 3; i++) put16(pkt + 28 + 4 * i, m->counts[i]);
            unsigned n = m->dmp_packet_size > 64 ? 64 : m->dmp_packet_size;
            for (unsigned i = 0; i < n; i++) fifo_push(m, pkt[i]);
            m->reg[MPU_INT_STATUS] |= MPU_INT_DMP;
        }
    }
}

void mpu_cs(mpu6000_t *m, int low) {
    if (low && !m->cs_low) {
        m->cs_low = 1;
        m->first = 1;
        m->read_mask = 0;
        m->txn_garbled = 0;
    } else if (!low && m->cs_low) {
        m->cs_low = 0;
        if (m->read_mask == 0x3FFF && m->latched_idx && !m->latched_fully_read) {
            m->latched_fully_read = 1;
            m->latched_read_garbled = m->txn_garbled != 0;
            m->samples_read++;
            if (m->latched_early) mpu_violate(m, MPU_RULE_GYRO_STARTUP, MPU_GYRO_XOUT_H);
        }
        if (m->latch_pending) latch(m);
    }
}

static unsigned dmp_addr(const mpu6000_t *m) {
    return ((m->reg[MPU_BANK_SEL] & 0x1F) % MPU_DMP_BANKS) * 256u + m->reg[MPU_MEM_START_ADDR];
}

static void dmp_addr_inc(mpu6000_t *m) {
    if (++m->reg[MPU_MEM_START_ADDR] == 0)
        m->reg[MPU_BANK_SEL] = (uint8_t)((m->reg[MPU_BANK_SEL] & ~0x1F) |
                                         ((m->reg[MPU_BANK_SEL] + 1) & 0x1F));
}

static uint8_t reg_read(mpu6000_t *m, uint8_t r) {
    uint8_t v;
    switch (r) {
        case MPU_FIFO_COUNTH:
            return (uint8_t)(m->fifo_count >> 8);
        case MPU_FIFO_COUNTL:
            return (uint8_t)m->fifo_count;
        case MPU_FIFO_R_W:
            return fifo_pop(m);
        case MPU_MEM_R_W:
            BIT_SET(m->dmp_readback, dmp_addr(m));
            v = m->dmp_mem[dmp_addr(m)];
            dmp_addr_inc(m);
            return v;
        case MPU_INT_STATUS:
            v = m->reg[r];
            m->reg[r] = 0;  // all INT_STATUS bits clear on read
            m->events |= MPU_EV_INT_CLEAR;
            return v;
        default:
            if (r >= MPU_ACCEL_XOUT_H && r <= MPU_GYRO_ZOUT_L)
                m->read_mask |= (uint16_t)(1u << (r - MPU_ACCEL_XOUT_H));
            return m->reg[r & 0x7F];
    }
}

static void reg_write(mpu6000_t *m, uint8_t r, uint8_t v) {
    if (reg_read_only(r)) mpu_violate(m, MPU_RULE_READ_ONLY, r);
    if (reg_reserved(r)) mpu_violate(m, MPU_RULE_RESERVED, r);
    switch (r) {
        case MPU_WHO_AM_I:
        case MPU_INT_STATUS:
        case MPU_FIFO_COUNTH:
        case MPU_FIFO_COUNTL:
        case MPU_PRODUCT_ID:
            return;  // read-only
        case MPU_FIFO_R_W:
            fifo_push(m, v);
            return;
        case MPU_MEM_R_W:
            BIT_SET(m->dmp_written, dmp_addr(m));
            m->dmp_mem[dmp_addr(m)] = v;
            dmp_addr_inc(m);
            return;
        case MPU_PWR_MGMT_1:
            if (v & MPU_PWR1_DEVICE_RESET) {
                mpu_device_reset(m);
                return;
            }
            if ((m->reg[r] ^ v) & MPU_PWR1_SLEEP) {
                m->events |= MPU_EV_CLOCK;
                if (!(v & MPU_PWR1_SLEEP)) m->gyro_valid_from = m->now_s + MPU_GYRO_STARTUP_S;
            }
            m->reg[r] = v;
            return;
        case MPU_USER_CTRL:
            if ((v & MPU_UC_DMP_EN) && !(m->reg[r] & MPU_UC_DMP_EN) && m->dmp_desc) {
                int bad_reg = -1;
                m->dmp_running = dmp_load_ok(m, &bad_reg);
                if (!m->dmp_running) mpu_violate(m, MPU_RULE_DMP_LOAD, bad_reg);
            }
            if (!(v & MPU_UC_DMP_EN)) m->dmp_running = 0;
            if (v & MPU_UC_FIFO_RESET) m->fifo_rd = m->fifo_count = 0;
            if (v & MPU_UC_SIG_COND_RESET)
                memset(&m->reg[MPU_ACCEL_XOUT_H], 0, MPU_GYRO_ZOUT_L - MPU_ACCEL_XOUT_H + 1);
            if (v & MPU_UC_DMP_RESET) {
                m->q[0] = 1.0;
                m->q[1] = m->q[2] = m->q[3] = 0.0;
            }
            m->reg[r] = v & ~(MPU_UC_DMP_RESET | MPU_UC_FIFO_RESET | 0x02 | MPU_UC_SIG_COND_RESET);
            return;
        case MPU_SIGNAL_PATH_RESET:
            if ((v & 0x7) == 0x7) m->signal_path_needed = 0;
            if (v & 0x7) m->signal_path_until = m->now_s + MPU_SIGNAL_PATH_WAIT_S;
            if (v & 0x7) memset(&m->reg[MPU_ACCEL_XOUT_H], 0, MPU_GYRO_ZOUT_L - MPU_ACCEL_XOUT_H + 1);
            if (v & 0x7) mpu_filter_reset(m);  // the digital signal paths restart
            return;  // self-clearing
        case MPU_INT_PIN_CFG:
            m->reg[r] = v;
            m->events |= MPU_EV_PIN_CFG;
            return;
        default:
            if (r >= MPU_ACCEL_XOUT_H && r <= MPU_GYRO_ZOUT_L) return;  // read-only
            m->reg[r & 0x7F] = v;
            return;
    }
}

uint8_t mpu_spi_byte(mpu6000_t *m, uint8_t mosi, mpu_access_t *acc, int *has_access) {
    *has_access = 0;
    if (!m->cs_low) return 0;
    if (m->first) {
        m->first = 0;
        m->rd = (mosi & 0x80) != 0;
        m->addr = mosi & 0x7F;
        return 0;
    }
    uint8_t r = m->addr;
    uint8_t out = 0;
    int data_reg = r >= MPU_ACCEL_XOUT_H && r <= MPU_GYRO_ZOUT_L;
    if (m->now_s < m->reset_until || m->now_s < m->power_on_until) {
        // in reset: nothing answers, nothing is stored
        mpu_violate(m, m->now_s < m->power_on_until ? MPU_RULE_POWER_ON : MPU_RULE_RESET_WAIT, r);
        acc->reg = r;
        acc->is_read = (uint8_t)m->rd;
        acc->value = m->rd ? 0 : mosi;
        *has_access = 1;
        if (r != MPU_FIFO_R_W && r != MPU_MEM_R_W) m->addr = (uint8_t)((r + 1) & 0x7F);
        return 0;
    }
    if (m->now_s < m->signal_path_until) mpu_violate(m, MPU_RULE_SIGNAL_PATH_WAIT, r);
    if (m->rd && data_reg) {
        if (m->signal_path_needed) mpu_violate(m, MPU_RULE_SIGNAL_PATH_RESET, r);
        if (!(m->reg[MPU_USER_CTRL] & MPU_UC_I2C_IF_DIS)) mpu_violate(m, MPU_RULE_I2C_IF_DIS, r);
    }
    if (m->rd) {
        out = reg_read(m, r);
        acc->value = out;
        // INT_RD_CLEAR: any read clears the latched interrupt
        if (m->reg[MPU_INT_PIN_CFG] & MPU_PIN_INT_RD_CLEAR) m->events |= MPU_EV_INT_CLEAR;
    } else {
        reg_write(m, r, mosi);
        acc->value = mosi;
    }
    acc->reg = r;
    acc->is_read = (uint8_t)m->rd;
    *has_access = 1;
    // burst: the address auto-increments, except on the FIFO and DMP memory ports
    if (r != MPU_FIFO_R_W && r != MPU_MEM_R_W) m->addr = (uint8_t)((r + 1) & 0x7F);
    return out;
}

const char *mpu_reg_name(uint8_t reg) {
    switch (reg) {
        case MPU_SMPLRT_DIV: return "SMPLRT_DIV";
        case MPU_CONFIG: return "CONFIG";
        case MPU_GYRO_CONFIG: return "GYRO_CONFIG";
        case MPU_ACCEL_CONFIG: return "ACCEL_CONFIG";
        case MPU_FIFO_EN: return "FIFO_EN";
        case MPU_INT_PIN_CFG: return "INT_PIN_CFG";
        case MPU_INT_ENABLE: return "INT_ENABLE";
        case MPU_INT_STATUS: return "INT_STATUS";
        case MPU_SIGNAL_PATH_RESET: return "SIGNAL_PATH_RESET";
        case MPU_USER_CTRL: return "USER_CTRL";
        case MPU_PWR_MGMT_1: return "PWR_MGMT_1";
        case MPU_PWR_MGMT_2: return "PWR_MGMT_2";
        case MPU_BANK_SEL: return "BANK_SEL";
        case MPU_MEM_START_ADDR: return "MEM_START_ADDR";
        case MPU_MEM_R_W: return "MEM_R_W";
        case MPU_DMP_CFG_1: return "DMP_CFG_1";
        case MPU_DMP_CFG_2: return "DMP_CFG_2";
        case MPU_FIFO_COUNTH: return "FIFO_COUNTH";
        case MPU_FIFO_COUNTL: return "FIFO_COUNTL";
        case MPU_FIFO_R_W: return "FIFO_R_W";
        case MPU_WHO_AM_I: return "WHO_AM_I";
        default: return "";
    }
}
