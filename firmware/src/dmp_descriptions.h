// DMP image descriptions: what a known InvenSense DMP image needs to run on an MPU-6000.
//
// Plain C (no AVR headers): the firmware's loader follows it (built with DMP_IMAGE=... and
// DMP_KIND=...), and the emulator (firmware/emulator) checks a load sequence against it. The
// images themselves are user-supplied (InvenSense licence): see firmware/dmp/README.md.
//
// Facts per image (public: the start address and configuration each vendor driver writes):
// - MotionApps 2.0 (i2cdevlib MPU6050_6Axis_MotionApps20, 1929 bytes): program start 0x0300,
//   42-byte FIFO packet (quaternion q30, gyro, accel in 32-bit slots), gyro +-2000 deg/s,
//   sample rate 1 kHz / (1 + 4) = 200 Hz, DLPF_CFG 3 (42 Hz).
// - eMD 6.x (Embedded MotionDriver 6.12 inv_mpu_dmp_motion_driver.c, 3062 bytes): program start
//   0x0400, 28-byte packet with 6-axis low-power quaternion + raw accel + raw gyro (16 + 6 + 6),
//   gyro +-2000 deg/s, 200 Hz, DLPF_CFG 2 (98 Hz, half the rate as eMD's mpu_set_sample_rate).
// Both: the DMP's FIFO rate divider is a big-endian u16 at DMP memory 0x0216 (bank 2, 0x16):
// FIFO rate = 200 Hz / (1 + divider). The loader writes it after the image (the "update").
#ifndef IMU_BENCH_DMP_DESCRIPTIONS_H
#define IMU_BENCH_DMP_DESCRIPTIONS_H

#include <stdint.h>

typedef struct dmp_image_desc {
    const char *name;
    uint16_t code_size;     // bytes of the image, loaded at DMP memory 0
    uint16_t start_addr;    // program start: DMP_CFG_1 (high) / DMP_CFG_2 (low)
    uint8_t packet_size;    // FIFO bytes per DMP packet (quaternion first, 4 x int32 q30 BE)
    uint8_t gyro_fs_sel;    // GYRO_CONFIG FS_SEL the image's scaling assumes (3 = +-2000 deg/s)
    uint8_t accel_fs_sel;   // ACCEL_CONFIG AFS_SEL (0 = +-2 g)
    uint8_t smplrt_div;     // SMPLRT_DIV: the DMP runs at 1 kHz / (1 + div) = 200 Hz
    uint8_t dlpf_cfg;       // CONFIG DLPF_CFG
    uint16_t fifo_rate_hz;  // DMP output rate written by the update below
} dmp_image_desc_t;

#define DMP_RATE_HZ 200u
#define DMP_FIFO_RATE_ADDR 0x0216u  // big-endian u16 divider: 200 Hz / (1 + divider)

#define DMP_IMAGE_DESC_MOTIONAPPS20 {"motionapps20", 1929u, 0x0300u, 42u, 3u, 0u, 4u, 3u, 100u}
#define DMP_IMAGE_DESC_EMD6 {"emd6", 3062u, 0x0400u, 28u, 3u, 0u, 4u, 2u, 100u}

#endif
