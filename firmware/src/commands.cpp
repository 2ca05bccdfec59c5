#include "commands.hpp"

#include "mpu6000.hpp"
#include "protocol_gen.h"
#include "telemetry.hpp"
#include "timebase.hpp"

namespace commands {

namespace {
uint32_t u32le(const uint8_t* p) {
    return static_cast<uint32_t>(p[0]) | static_cast<uint32_t>(p[1]) << 8 |
           static_cast<uint32_t>(p[2]) << 16 | static_cast<uint32_t>(p[3]) << 24;
}

// Payload length each known command must have; -1 for an unknown type.
int16_t expected_len(uint8_t type) {
    switch (type) {
        case PROTO_TYPE_PING: return PROTO_LEN_PING;
        case PROTO_TYPE_START_STREAM: return PROTO_LEN_START_STREAM;
        case PROTO_TYPE_STOP_STREAM: return PROTO_LEN_STOP_STREAM;
        case PROTO_TYPE_SET_RATE: return PROTO_LEN_SET_RATE;
        case PROTO_TYPE_GET_CONFIG: return PROTO_LEN_GET_CONFIG;
        case PROTO_TYPE_GET_STATUS: return PROTO_LEN_GET_STATUS;
        case PROTO_TYPE_SELF_TEST: return PROTO_LEN_SELF_TEST;
        default: return -1;
    }
}
}  // namespace

Result handle(uint8_t type, uint16_t seq, const uint8_t* payload, uint8_t len) {
    Result result{false};
    const int16_t want = expected_len(type);
    if (want < 0) {
        telemetry::send_ack(type, seq, PROTO_ACK_STATUS_UNSUPPORTED);
        telemetry::send_error(PROTO_ERROR_CODE_BAD_COMMAND, type);
        return result;
    }
    if (len != want) {
        telemetry::send_ack(type, seq, PROTO_ACK_STATUS_BAD_ARGUMENT);
        return result;
    }

    uint8_t status = PROTO_ACK_STATUS_OK;
    switch (type) {
        case PROTO_TYPE_PING:
            telemetry::send_pong(u32le(payload + PROTO_OFF_PING_nonce), timebase::micros());
            break;
        case PROTO_TYPE_START_STREAM:
            telemetry::g_stream_enabled = true;
            break;
        case PROTO_TYPE_STOP_STREAM:
            telemetry::g_stream_enabled = false;
            break;
        case PROTO_TYPE_SET_RATE: {
            uint8_t bad_register = 0;
            switch (mpu6000::set_rate(payload[PROTO_OFF_SET_RATE_smplrt_div],
                                      payload[PROTO_OFF_SET_RATE_dlpf_cfg], &bad_register)) {
                case mpu6000::RateResult::kOk:
                    result.config_changed = true;
                    break;
                case mpu6000::RateResult::kBadArgument:
                    status = PROTO_ACK_STATUS_BAD_ARGUMENT;
                    break;
                case mpu6000::RateResult::kBusy:
                    status = PROTO_ACK_STATUS_BUSY;  // sensor not streaming: nothing applied
                    break;
                case mpu6000::RateResult::kVerifyFailed:
                    // Read-back mismatch: the driver restarts its bring-up (with the new values).
                    telemetry::send_ack(type, seq, PROTO_ACK_STATUS_BUSY);
                    ++telemetry::g_counters.spi_faults;
                    telemetry::send_error(PROTO_ERROR_CODE_CONFIG_VERIFY, bad_register);
                    return result;
            }
            break;
        }
        case PROTO_TYPE_GET_CONFIG:
            telemetry::send_hello();
            break;
        case PROTO_TYPE_GET_STATUS:
            telemetry::send_status();
            break;
        case PROTO_TYPE_SELF_TEST:
            // Runs in mpu6000::poll; SELF_TEST_RESULT follows when it is done (main.cpp).
            switch (mpu6000::start_self_test()) {
                case mpu6000::SelfTestStart::kStarted:
                    break;
                case mpu6000::SelfTestStart::kBusy:
                    status = PROTO_ACK_STATUS_BUSY;
                    break;
                case mpu6000::SelfTestStart::kUnsupported:
                    status = PROTO_ACK_STATUS_UNSUPPORTED;
                    break;
            }
            break;
        default:
            break;
    }
    telemetry::send_ack(type, seq, status);
    return result;
}

}  // namespace commands
