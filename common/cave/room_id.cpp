#include "common/cave/room_id.hpp"

#include <cassert>
#include <charconv>

namespace grotto::cave {
namespace {

constexpr int kSlotBits = 13;
constexpr int kCoordBits = 17;
static_assert(kSlotCount <= (1 << kSlotBits));
static_assert(2 * kSectorCoordLimit < (1 << kCoordBits));
static_assert(kSlotBits + 3 * kCoordBits == 64);

// Parses a decimal integer with an optional '-' and no leading zeros, '+' or spaces, so that
// every id has exactly one text form.
bool parse_int(std::string_view text, int64_t& out) {
  std::string_view digits = text.starts_with('-') ? text.substr(1) : text;
  if (digits.empty() || digits.size() > 9) return false;
  if (digits.size() > 1 && digits.front() == '0') return false;
  if (text == "-0") return false;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
  return ec == std::errc() && end == text.data() + text.size();
}

Error bad_id(std::string_view text, std::string_view why) {
  std::string shown(text.substr(0, 64));
  if (text.size() > 64) shown += "...";
  return invalid_argument("malformed room id '" + shown + "': " + std::string(why) +
                          " (expected <sx>.<sy>.<sz>.<r|x|y|z><n>, e.g. 3.-1.0.r12)");
}

}  // namespace

bool in_range(SectorCoord s) {
  for (int a = 0; a < 3; ++a) {
    if (s[a] < -kSectorCoordLimit || s[a] > kSectorCoordLimit) return false;
  }
  return true;
}

SectorCoord neighbour(SectorCoord s, int axis, int step) {
  s[axis] += step;
  return s;
}

std::string to_string(SectorCoord s) {
  return std::to_string(s.x) + "." + std::to_string(s.y) + "." + std::to_string(s.z);
}

RoomId RoomId::interior(SectorCoord sector, int index) {
  assert(in_range(sector) && index >= 0 && index < kMaxInteriorRooms);
  return RoomId(sector, static_cast<uint16_t>(index));
}

RoomId RoomId::gate(SectorCoord lower_sector, int axis, int index) {
  assert(in_range(lower_sector) && axis >= 0 && axis < 3 && index >= 0 && index < kMaxGatesPerFace);
  return RoomId(lower_sector,
                static_cast<uint16_t>(kGateSlotBase + axis * kMaxGatesPerFace + index));
}

uint64_t RoomId::packed() const {
  uint64_t bits = slot_;
  for (int a = 0; a < 3; ++a) {
    uint64_t coord = static_cast<uint64_t>(sector_[a] + kSectorCoordLimit);
    bits |= coord << (kSlotBits + a * kCoordBits);
  }
  return bits;
}

Result<RoomId> RoomId::unpack(uint64_t packed) {
  uint64_t slot = packed & ((1u << kSlotBits) - 1);
  if (slot >= static_cast<uint64_t>(kSlotCount)) {
    return invalid_argument("room id " + std::to_string(packed) + " has slot " +
                            std::to_string(slot) + ", beyond the last slot " +
                            std::to_string(kSlotCount - 1));
  }
  SectorCoord s;
  for (int a = 0; a < 3; ++a) {
    uint64_t coord = (packed >> (kSlotBits + a * kCoordBits)) & ((1u << kCoordBits) - 1);
    s[a] = static_cast<int32_t>(coord) - kSectorCoordLimit;
  }
  if (!in_range(s)) {
    return invalid_argument("room id " + std::to_string(packed) + " names sector " +
                            cave::to_string(s) + ", outside +/-" +
                            std::to_string(kSectorCoordLimit));
  }
  return RoomId(s, static_cast<uint16_t>(slot));
}

std::string RoomId::to_string() const {
  char kind = is_gate() ? "xyz"[gate_axis()] : 'r';
  return cave::to_string(sector_) + "." + kind + std::to_string(index());
}

Result<RoomId> RoomId::parse(std::string_view text) {
  if (text.size() > 64) return bad_id(text, "longer than 64 characters");
  std::string_view parts[4];
  size_t start = 0;
  for (int i = 0; i < 4; ++i) {
    size_t dot = i < 3 ? text.find('.', start) : text.size();
    if (dot == std::string_view::npos) return bad_id(text, "expected four dot-separated parts");
    parts[i] = text.substr(start, dot - start);
    start = dot + 1;
  }
  SectorCoord s;
  for (int a = 0; a < 3; ++a) {
    int64_t v = 0;
    if (!parse_int(parts[a], v)) return bad_id(text, "sector coordinate is not an integer");
    if (v < -kSectorCoordLimit || v > kSectorCoordLimit) {
      return bad_id(text, "sector coordinate outside +/-" + std::to_string(kSectorCoordLimit));
    }
    s[a] = static_cast<int32_t>(v);
  }
  std::string_view slot = parts[3];
  if (slot.empty()) return bad_id(text, "missing room kind and index");
  int64_t index = 0;
  if (!parse_int(slot.substr(1), index) || index < 0) {
    return bad_id(text, "room index is not a non-negative integer");
  }
  switch (slot.front()) {
    case 'r':
      if (index >= kMaxInteriorRooms) {
        return bad_id(text, "interior index above " + std::to_string(kMaxInteriorRooms - 1));
      }
      return RoomId::interior(s, static_cast<int>(index));
    case 'x':
    case 'y':
    case 'z':
      if (index >= kMaxGatesPerFace) {
        return bad_id(text, "gate index above " + std::to_string(kMaxGatesPerFace - 1));
      }
      return RoomId::gate(s, slot.front() - 'x', static_cast<int>(index));
    default:
      return bad_id(text, "room kind must be r, x, y or z");
  }
}

}  // namespace grotto::cave
