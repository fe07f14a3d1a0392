#include "proto/room_path.hpp"

#include <array>
#include <charconv>

namespace grotto::proto {
namespace {

constexpr std::string_view kForm = "/rooms/v<version>/<seed>/<params>/<lod>/<room id>";

Error path_error(std::string_view problem) {
  return Error{ErrorCode::kBadMessage,
               "room path " + std::string(kForm) + ": " + std::string(problem)};
}

// A decimal integer in [0, max] in its one text form (no sign, no leading zeros).
std::optional<uint32_t> small_decimal(std::string_view s, uint32_t max) {
  if (s.empty() || s.size() > 5 || (s.size() > 1 && s[0] == '0')) return std::nullopt;
  uint32_t v = 0;
  auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size() || v > max) return std::nullopt;
  return v;
}

}  // namespace

std::string room_path(const RoomPath& room) {
  return std::string(kRoomPathPrefix) + "v" + std::to_string(room.version) + "/" +
         std::to_string(room.seed) + "/" + digest_text(room.params) + "/" +
         std::to_string(room.lod) + "/" + room.id.to_string();
}

Result<RoomPath> parse_room_path(std::string_view path) {
  if (!path.starts_with(kRoomPathPrefix)) return path_error("does not start with /rooms/");
  std::string_view rest = path.substr(kRoomPathPrefix.size());
  std::array<std::string_view, 5> parts;
  for (size_t i = 0; i < parts.size(); ++i) {
    size_t slash = i + 1 < parts.size() ? rest.find('/') : rest.size();
    if (slash == std::string_view::npos) {
      return path_error("has " + std::to_string(i + 1) + " parts after /rooms/, not 5");
    }
    parts[i] = rest.substr(0, slash);
    rest = rest.substr(std::min(slash + 1, rest.size()));
  }
  if (parts[4].find('/') != std::string_view::npos) {
    return path_error("has more than 5 parts after /rooms/");
  }
  RoomPath out;
  auto version = parts[0].starts_with('v') ? small_decimal(parts[0].substr(1), 65535)
                                           : std::optional<uint32_t>{};
  if (!version || *version == 0) {
    return path_error(
        "the version must be 'v' and an integer in [1, 65535], no leading zeros "
        "(got '" +
        echo(parts[0]) + "')");
  }
  out.version = *version;
  auto seed = parse_seed_text(parts[1], "seed");
  if (!seed) return path_error(seed.error().message);
  out.seed = *seed;
  auto params = parse_digest_text(parts[2], "params");
  if (!params) return path_error(params.error().message);
  out.params = *params;
  auto lod = small_decimal(parts[3], 255);
  if (!lod) {
    return path_error("the lod must be an integer in [0, 255], no leading zeros (got '" +
                      echo(parts[3]) + "')");
  }
  out.lod = *lod;
  auto id = cave::RoomId::parse(parts[4]);
  if (!id) {
    return Error{ErrorCode::kInvalidRoomId,
                 "room path " + std::string(kForm) + ": " + id.error().message};
  }
  out.id = *id;
  return out;
}

}  // namespace grotto::proto
