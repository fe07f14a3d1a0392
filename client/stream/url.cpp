#include "client/stream/url.hpp"

#include <charconv>
#include <string_view>

#include "proto/messages.hpp"

namespace grotto::stream {

Result<Url> parse_url(const std::string& text) {
  auto bad = [&](const std::string& why) {
    return Error{ErrorCode::kInvalidArgument, "server url '" + proto::echo(text) + "': " + why +
                                                  " (expected ws://host:port/ws)"};
  };
  constexpr std::string_view kScheme = "ws://";
  if (text.rfind("wss://", 0) == 0) return bad("wss is not supported; put TLS in a proxy");
  if (text.rfind(kScheme, 0) != 0) return bad("must start with ws://");
  std::string_view rest = std::string_view(text).substr(kScheme.size());
  Url url;
  auto slash = rest.find('/');
  std::string_view authority = rest.substr(0, slash);
  if (slash != std::string_view::npos) url.path = std::string(rest.substr(slash));
  auto colon = authority.rfind(':');
  if (authority.empty() || colon == 0) return bad("no host");
  url.host = std::string(authority.substr(0, colon));
  if (colon != std::string_view::npos) {
    std::string_view port = authority.substr(colon + 1);
    unsigned value = 0;
    auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), value);
    if (port.empty() || ec != std::errc{} || end != port.data() + port.size() || value == 0 ||
        value > 65535) {
      return bad("port must be a number in [1, 65535]");
    }
    url.port = static_cast<uint16_t>(value);
  }
  if (url.host.find_first_of(" /?#@") != std::string::npos) return bad("invalid host");
  return url;
}

}  // namespace grotto::stream
