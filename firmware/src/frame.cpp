#include "frame.hpp"

#ifdef __AVR__
#include <util/crc16.h>  // _crc_xmodem_update: poly 0x1021, MSB first, hand-tuned asm
#endif

namespace frame {

uint16_t crc16_update(uint16_t crc, uint8_t byte) {
#ifdef __AVR__
    // Seeded with 0xFFFF (PROTO_CRC_INIT) this is CRC-16/CCITT-FALSE.
    return _crc_xmodem_update(crc, byte);
#else
    crc ^= static_cast<uint16_t>(byte) << 8;
    for (uint8_t i = 0; i < 8; ++i) {
        crc = (crc & 0x8000u) ? static_cast<uint16_t>((crc << 1) ^ 0x1021u)
                              : static_cast<uint16_t>(crc << 1);
    }
    return crc;
#endif
}

uint16_t crc16(const uint8_t* data, uint8_t len, uint16_t crc) {
    for (uint8_t i = 0; i < len; ++i) {
        crc = crc16_update(crc, data[i]);
    }
    return crc;
}

uint8_t finish(uint8_t* buf, uint8_t type, uint8_t len, uint16_t seq) {
    buf[0] = PROTO_SYNC0;
    buf[1] = PROTO_SYNC1;
    buf[2] = type;
    buf[3] = len;
    buf[4] = static_cast<uint8_t>(seq);
    buf[5] = static_cast<uint8_t>(seq >> 8);
    // The CRC covers type, length, seq and payload: bytes 2 .. 5 + len.
    const uint16_t crc = crc16(buf + 2, static_cast<uint8_t>(PROTO_HEADER_LEN - 2 + len));
    buf[PROTO_HEADER_LEN + len] = static_cast<uint8_t>(crc);
    buf[PROTO_HEADER_LEN + len + 1] = static_cast<uint8_t>(crc >> 8);
    return static_cast<uint8_t>(PROTO_HEADER_LEN + len + PROTO_CRC_LEN);
}

namespace {
inline int16_t be16(const uint8_t* p) {
    return static_cast<int16_t>(static_cast<uint16_t>(p[0]) << 8 | p[1]);
}
}  // namespace

uint8_t encode_imu_sample(uint8_t* buf, uint16_t seq, uint32_t t_us,
                          const uint8_t raw[kImuRawLen], uint8_t flags) {
    // The generated writer keeps the layout in step with the spec; the sensor's big-endian
    // counts pass through unchanged (be16 here, big-endian writes there).
    proto_put_IMU_SAMPLE(payload(buf), t_us, be16(raw + 0), be16(raw + 2), be16(raw + 4),
                         be16(raw + 6), be16(raw + 8), be16(raw + 10), be16(raw + 12), flags);
    return finish(buf, PROTO_TYPE_IMU_SAMPLE, PROTO_LEN_IMU_SAMPLE, seq);
}

void Parser::drop(uint8_t n) {
    for (uint8_t i = n; i < size_; ++i) {
        buf_[i - n] = buf_[i];
    }
    size_ = static_cast<uint8_t>(size_ - n);
}

void Parser::feed(uint8_t byte, Handler on_frame, void* ctx) {
    buf_[size_++] = byte;  // room: size_ < kMaxFrameLen always holds between calls (see below)
    for (;;) {
        uint8_t skip = 0;
        while (skip < size_ && buf_[skip] != PROTO_SYNC0) {
            ++skip;
        }
        drop(skip);
        if (size_ < 2) {
            return;
        }
        if (buf_[1] != PROTO_SYNC1) {
            drop(1);
            continue;
        }
        if (size_ < 4) {
            return;
        }
        const uint8_t len = buf_[3];
        if (len > PROTO_MAX_PAYLOAD) {
            drop(1);  // impossible length: not a frame (not counted as a CRC error)
            continue;
        }
        const uint8_t total = static_cast<uint8_t>(PROTO_HEADER_LEN + len + PROTO_CRC_LEN);
        if (size_ < total) {
            return;  // total <= kMaxFrameLen, so the next byte still fits
        }
        const uint16_t want = crc16(buf_ + 2, static_cast<uint8_t>(PROTO_HEADER_LEN - 2 + len));
        const uint16_t got = static_cast<uint16_t>(buf_[PROTO_HEADER_LEN + len] |
                                                   buf_[PROTO_HEADER_LEN + len + 1] << 8);
        if (want != got) {
            ++crc_errors_;
            drop(1);
            continue;
        }
        on_frame(ctx, buf_[2], static_cast<uint16_t>(buf_[4] | buf_[5] << 8),
                 buf_ + PROTO_HEADER_LEN, len);
        drop(total);
    }
}

}  // namespace frame
