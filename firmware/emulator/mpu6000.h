// MPU-6000 register-level model for the APM 2.6 emulator (no simavr dependency).
//
// The glue (apm_emu.c) drives it: chip select edges, SPI bytes, sample-clock ticks. The model
// answers bytes, keeps the register file / FIFO / DMP memory, and reports what the glue must do
// (start the sample clock, clear the INT pin, ...) through `events`.
#pragma once

#include <stdint.h>

#include "dmp_descriptions.h"  // firmware/src: the DMP image descriptions

// Register addresses (MPU-6000 register map RM-MPU-6000A-00 rev 4.2).
enum {
    MPU_SELF_TEST_X = 0x0D,
    MPU_SELF_TEST_Y = 0x0E,
    MPU_SELF_TEST_Z = 0x0F,
    MPU_SELF_TEST_A = 0x10,
    MPU_PRODUCT_ID = 0x0C,
    MPU_SMPLRT_DIV = 0x19,
    MPU_CONFIG = 0x1A,
    MPU_GYRO_CONFIG = 0x1B,
    MPU_ACCEL_CONFIG = 0x1C,
    MPU_FIFO_EN = 0x23,
    MPU_INT_PIN_CFG = 0x37,
    MPU_INT_ENABLE = 0x38,
    MPU_INT_STATUS = 0x3A,
    MPU_ACCEL_XOUT_H = 0x3B,
    MPU_TEMP_OUT_H = 0x41,
    MPU_GYRO_XOUT_H = 0x43,
    MPU_GYRO_ZOUT_L = 0x48,
    MPU_SIGNAL_PATH_RESET = 0x68,
    MPU_USER_CTRL = 0x6A,
    MPU_PWR_MGMT_1 = 0x6B,
    MPU_PWR_MGMT_2 = 0x6C,
    MPU_BANK_SEL = 0x6D,
    MPU_MEM_START_ADDR = 0x6E,
    MPU_MEM_R_W = 0x6F,
    MPU_DMP_CFG_1 = 0x70,
    MPU_DMP_CFG_2 = 0x71,
    MPU_FIFO_COUNTH = 0x72,
    MPU_FIFO_COUNTL = 0x73,
    MPU_FIFO_R_W = 0x74,
    MPU_WHO_AM_I = 0x75,
};

// Bits
#define MPU_PWR1_DEVICE_RESET 0x80
#define MPU_PWR1_SLEEP 0x40
#define MPU_INT_DATA_RDY 0x01
#define MPU_INT_DMP 0x02
#define MPU_INT_FIFO_OFLOW 0x10
#define MPU_PIN_INT_LEVEL 0x80  // 1: active low
#define MPU_PIN_LATCH_INT_EN 0x20
#define MPU_PIN_INT_RD_CLEAR 0x10
#define MPU_UC_DMP_EN 0x80
#define MPU_UC_FIFO_EN 0x40
#define MPU_UC_I2C_IF_DIS 0x10
#define MPU_UC_DMP_RESET 0x08
#define MPU_UC_FIFO_RESET 0x04
#define MPU_UC_SIG_COND_RESET 0x01

#define MPU_FIFO_SIZE 1024
#define MPU_DMP_BANKS 16
#define MPU_DMP_MEM_SIZE (MPU_DMP_BANKS * 256)

// events the glue must act upon (bit mask, cleared by the glue)
#define MPU_EV_CLOCK 0x01      // SLEEP/reset changed: (re)start or stop the sample clock
#define MPU_EV_INT_CLEAR 0x02  // a read cleared the latched INT pin
#define MPU_EV_PIN_CFG 0x04    // INT_PIN_CFG changed: re-drive the INT pin
#define MPU_EV_RESET 0x08      // DEVICE_RESET happened

// Hardware rules: what the datasheet states and a real part would punish. Each broken rule is
// counted (with the time and register of its first occurrence) and named in the summary.
// PS = product specification PS-MPU-6000A-00 rev 3.4, RM = register map RM-MPU-6000A-00 rev 4.2.
enum mpu_rule {
    MPU_RULE_SPI_CLOCK,          // glue: > 1 MHz on a non-sensor register
    MPU_RULE_SPI_MODE,           // glue: CPOL != CPHA (the chip needs mode 0 or 3)
    MPU_RULE_SPI_BIT_ORDER,      // glue: DORD = 1 (LSB first)
    MPU_RULE_BARO_CS,            // glue: MS5611 /CS not high during an MPU transaction
    MPU_RULE_DRDY_EDGE,          // glue: INT6 does not sense the data-ready pulse's leading edge
    MPU_RULE_RESET_WAIT,         // access within 100 ms of DEVICE_RESET
    MPU_RULE_SIGNAL_PATH_RESET,  // sensor data used after DEVICE_RESET without SIGNAL_PATH_RESET
    MPU_RULE_SIGNAL_PATH_WAIT,   // access within 100 ms of SIGNAL_PATH_RESET
    MPU_RULE_GYRO_STARTUP,       // a sample taken < 30 ms after wake-up was read
    MPU_RULE_I2C_IF_DIS,         // sensor data read over SPI with the I2C interface enabled
    MPU_RULE_READ_ONLY,          // write to a read-only register
    MPU_RULE_RESERVED,           // write to a reserved (undocumented, unused) register
    MPU_RULE_DMP_LOAD,           // DMP enabled without the load sequence its image needs
    MPU_RULE_POWER_ON,           // access within the power-on start-up time
    MPU_RULE_COUNT
};
extern const char *const MPU_RULE_NAME[MPU_RULE_COUNT];
extern const char *const MPU_RULE_REF[MPU_RULE_COUNT];   // datasheet and page
extern const char *const MPU_RULE_TEXT[MPU_RULE_COUNT];  // what a real part does

#define MPU_RESET_WAIT_S 0.100        // RM p.41: DEVICE_RESET, wait 100 ms (SPI reset sequence)
#define MPU_SIGNAL_PATH_WAIT_S 0.100  // RM p.41: SIGNAL_PATH_RESET, wait 100 ms
#define MPU_GYRO_STARTUP_S 0.030      // PS p.12: gyroscope start-up time 30 ms
// Power-on: the part comes out of its power-on reset 100 ms after VDD is valid (the reset time of
// RM p.41; PS p.14 allows VDD itself to ramp for up to 100 ms). The AVR starts 65 ms after power-on
// (Arduino Mega fuses: 16K CK + 65 ms, ATmega2560 datasheet table 10-5), so the glue sets
// power_on_until = 0.100 - 0.065 s of emulated time.
#define MPU_POWER_ON_S 0.100

// DLPF (RM p.13): per DLPF_CFG the accelerometer's and the gyroscope's bandwidth (Hz) and delay
// (ms). The model filters each axis at the internal rate (1 kHz, 8 kHz with DLPF_CFG 0/7) with a
// pure delay and an all-pole section whose -3 dB bandwidth and DC group delay are the table's.
typedef struct mpu_dlpf_spec {
    double accel_bw_hz, accel_delay_ms, gyro_bw_hz, gyro_delay_ms;
} mpu_dlpf_spec_t;
extern const mpu_dlpf_spec_t MPU_DLPF[8];

typedef struct mpu_filter {
    double b0, a1, a2;  // y[k] = b0 x[k] - a1 y[k-1] - a2 y[k-2], unit DC gain
    double delay_s;     // pure delay ahead of it (DC group delay = table's delay)
    double y1[3], y2[3];
} mpu_filter_t;

// Design a filter of -3 dB bandwidth bw_hz and DC group delay delay_s at sample rate fs_hz
// (bw_hz <= 0 or delay_s <= 0: no filtering, only the delay).
void mpu_filter_design(mpu_filter_t *f, double bw_hz, double delay_s, double fs_hz);
// Its DC group delay (s) and -3 dB frequency (Hz), computed from the coefficients.
double mpu_filter_group_delay_s(const mpu_filter_t *f, double fs_hz);


typedef struct mpu_truth {
    double f[3];  // specific force, m/s^2, chip axes
    double w[3];  // angular rate, deg/s, chip axes
    double temp;  // die temperature, degC
} mpu_truth_t;

typedef struct mpu_access {
    uint8_t reg;
    uint8_t value;
    uint8_t is_read;
} mpu_access_t;

// PRODUCT_ID (0x0C): 0x58 = MPU-6000 rev D8 by default. Revisions C4/C5 (0x54/0x55, ES 0x14/0x15)
// count half the datasheet's LSB/g at every AFS_SEL (ArduPilot's driver; the C4/C5).
#define MPU_PRODUCT_ID_DEFAULT 0x58
int mpu_half_accel_sensitivity(uint8_t product_id);

typedef struct mpu6000 {
    uint8_t reg[128];
    uint8_t product_id;       // what PRODUCT_ID reads (the part's revision)
    uint8_t dmp_mem[MPU_DMP_MEM_SIZE];
    uint8_t fifo[MPU_FIFO_SIZE];
    unsigned fifo_rd, fifo_count;

    // SPI transaction state
    int cs_low;
    int first;     // next byte is the address byte
    int rd;        // current transaction reads
    uint8_t addr;  // current register address
    uint16_t read_mask;  // which of 0x3B..0x48 were read in this transaction

    // samples
    int16_t counts[7];        // last produced (ax ay az temp gx gy gz)
    int latch_pending;        // produced while CS was low: latched at CS rising edge
    uint64_t produced;        // samples produced (sample clock ticks while awake)
    uint64_t latched_idx;     // index (1-based) of the sample in the output registers; 0 none
    int latched_fully_read;   // the latched sample has been read completely at least once
    int txn_garbled;          // glue: a byte of this transaction reached the AVR corrupted
    int latched_read_garbled; // the latched sample's full read was garbled on the bus
    uint64_t samples_read;    // distinct samples read completely (all 14 bytes in one burst)
    uint64_t fifo_overflows;

    // sample bookkeeping for the sample log: a sample "retires" when it leaves the output
    // registers (replaced by the next one, DEVICE_RESET, or mpu_finish); read = it was burst-read
    double now_s;                 // set by the glue before mpu_sample
    double counts_t, latched_t;   // production time of counts[] / of the latched sample
    int16_t latched_counts[7];
    void (*retire)(void *ctx, uint64_t idx, double t, const int16_t c[7], int read);  // read: 0 no,
                                                                    // 1 yes, 2 garbled on the bus
    void *retire_ctx;

    // DMP stub
    double q[4];  // attitude quaternion integrated from the gyro truth (w x y z)
    unsigned dmp_packet_size;
    const dmp_image_desc_t *dmp_desc;  // the image the firmware must load (NULL: unchecked stub)
    uint8_t dmp_written[MPU_DMP_MEM_SIZE / 8], dmp_readback[MPU_DMP_MEM_SIZE / 8];  // bitmaps
    int dmp_running;                   // the DMP runs (loaded as its description requires)
    char dmp_problem[160];             // why the last DMP_EN did not start it ("" = it did)

    unsigned events;

    // DLPF: at the internal rate the glue takes the truth at (now - accel delay) and (now -
    // gyro delay) (mpu_dlpf_delays) and steps the filters (mpu_internal_tick); their output
    // (filtered: fx fy fz wx wy wz) is what a sample converts (temperature is not filtered)
    mpu_filter_t filt_accel, filt_gyro;
    int filt_cfg;              // DLPF_CFG the filters are designed for (-1: none yet)
    double filt_fs;            // ... and the internal rate
    int filt_settle;           // the next step starts the filters settled at their input
    double filtered[6];
    double power_on_until;     // registers unreachable before this time (power-on reset)

    // self-test (RM p.9-11): with XA/YA/ZA_ST (ACCEL_CONFIG bits 7..5) or XG/YG/ZG_ST
    // (GYRO_CONFIG bits 7..5) set, the actuation adds this to what the axis senses, ahead of the
    // DLPF like any force or rate (mpu_internal_tick); mpu_self_test sets it
    double st_accel_g[3];      // accelerometer response, g
    double st_gyro_dps[3];     // gyroscope response, deg/s

    // hardware rules (time: now_s, set by the glue before every call)
    uint64_t rule_count[MPU_RULE_COUNT];
    double rule_first_t[MPU_RULE_COUNT];
    int rule_first_reg[MPU_RULE_COUNT];
    double reset_until;        // in reset (DEVICE_RESET) until this time: registers unreachable
    double signal_path_until;  // signal path reset in progress until this time
    int signal_path_needed;    // DEVICE_RESET seen, SIGNAL_PATH_RESET (all three paths) not yet
    double gyro_valid_from;    // samples produced before this time carry no valid gyro data
    int latched_early;         // the latched sample was produced within the gyro start-up time
} mpu6000_t;

// Count a broken rule (reg: the register involved, or -1).
void mpu_violate(mpu6000_t *m, int rule, int reg);

void mpu_power_on(mpu6000_t *m, unsigned dmp_packet_size, uint8_t product_id);
// The part's self-test response: the factory trim its SELF_TEST registers hold (RM p.10-11)
// times 1 + a small per-axis deviation (a healthy part, within a few %), or, with fail != 0,
// a part that fails: accelerometer Y responds 35 % above its trim, gyroscope Z 45 % below
// (the product specification allows +-14 %, PS p.12-13).
void mpu_self_test(mpu6000_t *m, int fail);
void mpu_device_reset(mpu6000_t *m);

// Chip select: low != 0 starts a transaction, 0 ends it.
void mpu_cs(mpu6000_t *m, int low);
// One SPI byte (only while CS is low). Returns the MISO byte; *acc is filled and 1 returned in
// *has_access when a register was read or written.
uint8_t mpu_spi_byte(mpu6000_t *m, uint8_t mosi, mpu_access_t *acc, int *has_access);

int mpu_awake(const mpu6000_t *m);
// Sample period in units of the 8 kHz base clock (125 us): 8 (1 kHz) or 1 (8 kHz) x (1 + div).
unsigned mpu_period_ticks_8k(const mpu6000_t *m);
// The internal rate (Hz) for the current DLPF_CFG: 8000 with 0 or 7, else 1000.
double mpu_internal_rate_hz(const mpu6000_t *m);
// The pure delays (s) ahead of the accel and gyro filters for the current DLPF_CFG (designs
// the filters for it first).
void mpu_dlpf_delays(mpu6000_t *m, double *accel_s, double *gyro_s);
// One internal-rate step: accel from *a (the truth accel delay ago), gyro from *g.
void mpu_internal_tick(mpu6000_t *m, const mpu_truth_t *a, const mpu_truth_t *g);
// Drop the filter state: the next step starts settled at its input (wake, signal path reset).
void mpu_filter_reset(mpu6000_t *m);
// One sample-clock tick: convert truth with the configured full scale, latch (or defer), FIFO.
// When mpu_internal_tick ran, accel and gyro come from the DLPF's output instead of *t.
// dt_s is the sample period (for the DMP quaternion integration).
void mpu_sample(mpu6000_t *m, const mpu_truth_t *t, double dt_s);
// Whether a register is a "sensor data" register (fast SPI allowed).
int mpu_is_sensor_reg(uint8_t reg);
// Convert truth to counts with the current configuration.
void mpu_convert(const mpu6000_t *m, const mpu_truth_t *t, int16_t out[7]);
const char *mpu_reg_name(uint8_t reg);
// Retire the sample still in the output registers (call once at exit).
void mpu_finish(mpu6000_t *m);
