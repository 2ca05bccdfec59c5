// Host -> device commands: one validated frame in, its answer frames out (every command gets
// exactly one ACK; PING is answered PONG then ACK, GET_CONFIG HELLO then ACK, GET_STATUS STATUS
// then ACK, an unknown type ACK UNSUPPORTED then ERROR BAD_COMMAND).
#pragma once

#include <stdint.h>

namespace commands {

struct Result {
    bool config_changed;  // SET_RATE applied: flag the next sample CONFIG_CHANGED
};

Result handle(uint8_t type, uint16_t seq, const uint8_t* payload, uint8_t len);

}  // namespace commands
