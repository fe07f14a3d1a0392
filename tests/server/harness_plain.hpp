// The parts of the server harness (server_harness.hpp) whose declarations need no Beast or Asio
// headers, for test files that only talk HTTP and fetch a room or two: including this costs no
// Beast parse. Implemented in server_harness.cpp with the rest.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "common/cave/room_id.hpp"

namespace grotto::server_test {

struct HttpRequest {
  std::string method = "GET";
  std::string target;
  std::vector<std::pair<std::string, std::string>> headers;
};

struct HttpAnswer {
  int status = 0;  // 0: no answer (refused, reset, or none within the timeout)
  std::map<std::string, std::string> headers;  // names in lower case
  std::string body;
  std::string header(const std::string& lower_name) const {
    auto it = headers.find(lower_name);
    return it == headers.end() ? std::string() : it->second;
  }
};

// The requests in order over one kept-alive HTTP/1.1 connection (a HEAD answer is read without
// a body), each answer within `timeout`; stops at the first that gets none.
std::vector<HttpAnswer> http_exchange(uint16_t port, const std::vector<HttpRequest>& requests,
                                      std::chrono::milliseconds timeout = std::chrono::seconds{20});

// The binary room frame a WebSocket client gets for `room` at `lod` after a hello offering only
// `version` (and `token` when not empty); empty, with the test failed, if it gets anything else.
std::string websocket_room_frame(uint16_t port, cave::RoomId room, uint32_t lod, uint32_t version,
                                 const std::string& token = {});

}  // namespace grotto::server_test
