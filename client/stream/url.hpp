// The server address a Stream connects to. Pure: no network, no Beast.
#pragma once
#include <cstdint>
#include <string>

#include "common/core/result.hpp"

namespace grotto::stream {

struct Url {
  std::string host;
  uint16_t port = 80;
  std::string path = "/ws";
};

// Parses ws://host:port[/path] (default port 80, path /ws). wss:// is refused (TLS belongs in a
// proxy). Errors (kInvalidArgument) quote the url, name what is wrong and mention "url". Safe for
// untrusted input.
Result<Url> parse_url(const std::string& url);

}  // namespace grotto::stream
