// Frame envelope (protocol/spec.json): A5 5A | type | len | seq u16le | payload | crc u16le,
// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over type..payload.
//
// Portable: no AVR headers, so the host test suite compiles this file with g++ and checks it
// byte for byte against protocol/vectors.json.
#pragma once

#include <stdint.h>

#include "protocol_gen.h"

namespace frame {

static constexpr uint8_t kMaxFrameLen = PROTO_HEADER_LEN + PROTO_MAX_PAYLOAD + PROTO_CRC_LEN;
static constexpr uint8_t kImuRawLen = 14;  // ACCEL_XOUT_H..GYRO_ZOUT_L as read (big-endian)

uint16_t crc16_update(uint16_t crc, uint8_t byte);
uint16_t crc16(const uint8_t* data, uint8_t len, uint16_t crc = PROTO_CRC_INIT);

// Where a frame's payload goes in a buffer of kMaxFrameLen bytes.
inline uint8_t* payload(uint8_t* buf) { return buf + PROTO_HEADER_LEN; }

// Complete a frame whose payload (len bytes) is already at payload(buf): writes sync, type,
// length, seq and CRC. Returns the frame's total length.
uint8_t finish(uint8_t* buf, uint8_t type, uint8_t len, uint16_t seq);

// A whole IMU_SAMPLE frame from the 14 bytes burst-read from the sensor.
uint8_t encode_imu_sample(uint8_t* buf, uint16_t seq, uint32_t t_us,
                          const uint8_t raw[kImuRawLen], uint8_t flags);

// Receiver for host commands, fed one byte at a time. It keeps the bytes of the current
// candidate frame: a candidate whose length is > PROTO_MAX_PAYLOAD or whose CRC fails is
// rejected and the search restarts at the byte after its first sync byte (so a good frame that
// starts inside a corrupted one is still found); a good frame is consumed whole
// (protocol/README.md, "Receiving: resynchronisation").
class Parser {
  public:
    typedef void (*Handler)(void* ctx, uint8_t type, uint16_t seq, const uint8_t* payload,
                            uint8_t len);

    // Calls on_frame for every good frame this byte completes (usually none or one).
    void feed(uint8_t byte, Handler on_frame, void* ctx);

    uint16_t crc_errors() const { return crc_errors_; }

  private:
    void drop(uint8_t n);

    uint8_t buf_[kMaxFrameLen] = {};
    uint8_t size_ = 0;
    uint16_t crc_errors_ = 0;
};

}  // namespace frame
