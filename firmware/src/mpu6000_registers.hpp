// MPU-6000 registers and bits used by this firmware (and only those).
//
// Source: InvenSense "MPU-6000 and MPU-6050 Register Map and Descriptions", RM-MPU-6000A-00
// rev 4.2 (cited below as "RM p.N"), and the "MPU-6000 and MPU-6050 Product Specification",
// PS-MPU-6000A-00 rev 3.4 ("PS p.N"). Written from the datasheets in the layout PX4 uses for its
// InvenSense drivers: a namespace, an enum class of register addresses, one bit enum per register.
#pragma once

#include <stdint.h>

namespace mpu6000 {

// WHO_AM_I holds bits 6..1 of the I2C address; 0x68 whatever AD0 is (RM p.45).
static constexpr uint8_t kWhoAmI = 0x68;

// SPI: the first byte is R/W (bit 7, 1 = read) followed by the 7-bit register address;
// consecutive bytes auto-increment the address (burst) (PS p.37, section 9.5).
static constexpr uint8_t kDirRead = 0x80;

// SPI clock limits (PS p.15, section 6.4): 1 MHz for every register, 20 MHz for reading the
// sensor and interrupt registers only. Data latched on SCLK rising edge, changed on the falling
// edge, clock idles high: SPI mode 3 (PS p.37).
static constexpr uint32_t kSpiClockAllRegistersHz = 1000000UL;
static constexpr uint32_t kSpiClockSensorReadHz = 20000000UL;

enum class Register : uint8_t {
    // Part and revision: undocumented in RM rev 4.2 (inside the self-test/offset block); read
    // by ArduPilot's and PX4's MPU-6000 drivers. High nibble 0x5 (0x1: engineering sample),
    // low nibble the revision: 4/5 = C4/C5, which have half the accelerometer sensitivity.
    PRODUCT_ID = 0x0C,
    // Factory trim of the self-test response (RM p.9-11): XA_TEST[4:2] in bits 7..5 and
    // XG_TEST[4:0] in bits 4..0 of X/Y/Z; SELF_TEST_A holds the accelerometers' low bits.
    SELF_TEST_X = 0x0D,        // 13  RM p.9
    SELF_TEST_Y = 0x0E,        // 14  RM p.9
    SELF_TEST_Z = 0x0F,        // 15  RM p.9
    SELF_TEST_A = 0x10,        // 16  RM p.9
    SMPLRT_DIV = 0x19,         // 25  RM p.11
    CONFIG = 0x1A,             // 26  RM p.13
    GYRO_CONFIG = 0x1B,        // 27  RM p.14
    ACCEL_CONFIG = 0x1C,       // 28  RM p.15
    INT_PIN_CFG = 0x37,        // 55  RM p.26
    INT_ENABLE = 0x38,         // 56  RM p.27
    INT_STATUS = 0x3A,         // 58  RM p.28
    ACCEL_XOUT_H = 0x3B,       // 59  RM p.29; ..0x48 GYRO_ZOUT_L (RM p.29-31), 14 bytes
    SIGNAL_PATH_RESET = 0x68,  // 104 RM p.37
    USER_CTRL = 0x6A,          // 106 RM p.38
    PWR_MGMT_1 = 0x6B,         // 107 RM p.40
    // DMP memory access and program start: undocumented in RM rev 4.2 (listed as reserved);
    // known from InvenSense's Embedded MotionDriver sources.
    BANK_SEL = 0x6D,
    MEM_START_ADDR = 0x6E,
    MEM_R_W = 0x6F,
    DMP_CFG_1 = 0x70,          // program start address, high byte
    DMP_CFG_2 = 0x71,          // program start address, low byte
    FIFO_COUNTH = 0x72,        // 114 RM p.43 (FIFO_COUNTL follows)
    FIFO_R_W = 0x74,           // 116 RM p.44
    WHO_AM_I = 0x75,           // 117 RM p.45
};

// Length of the sensor burst ACCEL_XOUT_H..GYRO_ZOUT_L (accel 6, temp 2, gyro 6).
static constexpr uint8_t kSensorBurstLen = 14;
// The burst as read: INT_STATUS (0x3A) first, then ACCEL_XOUT_H (0x3B)..GYRO_ZOUT_L, one
// transaction (the address auto-increments, PS p.37), so its data-ready bit vouches for them.
static_assert(static_cast<uint8_t>(Register::INT_STATUS) + 1 ==
                  static_cast<uint8_t>(Register::ACCEL_XOUT_H),
              "the checked burst starts at INT_STATUS");

// CONFIG (RM p.13)
enum CONFIG_BIT : uint8_t {
    // DLPF_CFG[2:0]; 4 = accel 21 Hz / gyro 20 Hz bandwidth, ~8.5 ms delay, internal rate 1 kHz.
    DLPF_CFG_MASK = 0x07,
    DLPF_CFG_94HZ = 2,  // accel 94 Hz / gyro 98 Hz, ~3 ms delay (the self-test's)
    DLPF_CFG_20HZ = 4,
};
static constexpr uint8_t kDlpfCfgMax = 6;  // 7 is reserved (RM p.13)

// GYRO_CONFIG (RM p.14): XG_ST/YG_ST/ZG_ST (self-test), FS_SEL[4:3]
enum GYRO_CONFIG_BIT : uint8_t {
    XG_ST = 1 << 7,
    YG_ST = 1 << 6,
    ZG_ST = 1 << 5,
    FS_SEL_SHIFT = 3,
    FS_SEL_MASK = 0x18,
    FS_SEL_250_DPS = 0x00,  // FS_SEL = 0: +-250 deg/s, 131 LSB/(deg/s)
};

// ACCEL_CONFIG (RM p.15): XA_ST/YA_ST/ZA_ST (self-test), AFS_SEL[4:3]
enum ACCEL_CONFIG_BIT : uint8_t {
    XA_ST = 1 << 7,
    YA_ST = 1 << 6,
    ZA_ST = 1 << 5,
    AFS_SEL_SHIFT = 3,
    AFS_SEL_MASK = 0x18,
    AFS_SEL_2G = 0x00,  // AFS_SEL = 0: +-2 g, 16384 LSB/g
    AFS_SEL_8G = 0x10,  // AFS_SEL = 2: +-8 g, 4096 LSB/g (the accelerometer self-test's, RM p.11)
};

// INT_PIN_CFG (RM p.26)
enum INT_PIN_CFG_BIT : uint8_t {
    INT_LEVEL = 1 << 7,     // 1 = active low; we leave 0: active high
    INT_OPEN = 1 << 6,      // 1 = open drain; we leave 0: push-pull
    LATCH_INT_EN = 1 << 5,  // 1 = hold until cleared; we leave 0: 50 us pulse (PS p.15)
    INT_RD_CLEAR = 1 << 4,  // 1 = any read clears; 0 = only reading INT_STATUS clears
};

// INT_ENABLE (RM p.27)
enum INT_ENABLE_BIT : uint8_t {
    FIFO_OFLOW_EN = 1 << 4,
    DATA_RDY_EN = 1 << 0,
};

// INT_STATUS (RM p.28)
enum INT_STATUS_BIT : uint8_t {
    FIFO_OFLOW_INT = 1 << 4,
    DATA_RDY_INT = 1 << 0,
};

// SIGNAL_PATH_RESET (RM p.37)
enum SIGNAL_PATH_RESET_BIT : uint8_t {
    GYRO_RESET = 1 << 2,
    ACCEL_RESET = 1 << 1,
    TEMP_RESET = 1 << 0,
};

// USER_CTRL (RM p.38)
enum USER_CTRL_BIT : uint8_t {
    DMP_EN = 1 << 7,      // undocumented in RM rev 4.2 (reserved bit), from InvenSense's eMD
    FIFO_EN = 1 << 6,
    I2C_IF_DIS = 1 << 4,  // SPI only: keep the primary I2C interface disabled
    DMP_RESET = 1 << 3,   // undocumented, as DMP_EN
    FIFO_RESET = 1 << 2,
    SIG_COND_RESET = 1 << 0,
};

// PWR_MGMT_1 (RM p.40)
enum PWR_MGMT_1_BIT : uint8_t {
    DEVICE_RESET = 1 << 7,
    SLEEP = 1 << 6,       // set after reset: the reset value of PWR_MGMT_1 is 0x40 (RM p.8)
    CLKSEL_PLL_XGYRO = 1, // CLKSEL[2:0] = 1: PLL with X gyro reference, recommended (RM p.40)
};

}  // namespace mpu6000
