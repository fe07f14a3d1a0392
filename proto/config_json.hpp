// A JSON config file read into a flat map of scalar settings, for programs whose settings are
// CLI11 flags over a config file over defaults (grotto-server --config FILE). Only this reading
// touches JSON; the program checks each key's meaning, type and range itself.
#pragma once

#include <cstdint>
#include <map>
#include <string>

#include "common/core/result.hpp"

namespace grotto::proto {

// One setting's value as the file spelled it.
struct ConfigValue {
  enum class Kind { kBool, kInteger, kNumber, kString };
  Kind kind = Kind::kString;
  bool boolean = false;
  int64_t integer = 0;  // kInteger (an integer that fits int64; larger integers are kNumber)
  double number = 0;    // kInteger and kNumber
  std::string string;   // kString
};

// Which JSON type a value had, for error messages ("a string", "an integer").
const char* describe(ConfigValue::Kind kind);

inline constexpr std::size_t kMaxConfigFileBytes = 1 << 20;

// The file must hold one JSON object whose values are booleans, numbers or strings (no nesting).
// Errors (kInvalidArgument) name the file and, where there is one, the key: unreadable file, over
// kMaxConfigFileBytes, invalid JSON, not an object, a nested or null value.
Result<std::map<std::string, ConfigValue>> read_config_file(const std::string& path);
// The same for text already in memory; `origin` names it in messages.
Result<std::map<std::string, ConfigValue>> parse_config_text(const std::string& text,
                                                             const std::string& origin);

}  // namespace grotto::proto
