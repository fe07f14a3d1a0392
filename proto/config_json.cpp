#include "proto/config_json.hpp"

#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>

#include "proto/json_reader.hpp"
#include "proto/messages.hpp"

namespace grotto::proto {

const char* describe(ConfigValue::Kind kind) {
  switch (kind) {
    case ConfigValue::Kind::kBool:
      return "a boolean";
    case ConfigValue::Kind::kInteger:
      return "an integer";
    case ConfigValue::Kind::kNumber:
      return "a number";
    case ConfigValue::Kind::kString:
      return "a string";
  }
  return "a value";
}

Result<std::map<std::string, ConfigValue>> parse_config_text(const std::string& text,
                                                             const std::string& origin) {
  auto parsed = detail::parse_object(text, kMaxConfigFileBytes);
  if (!parsed) return invalid_argument(origin + ": " + parsed.error().message);
  std::map<std::string, ConfigValue> out;
  for (const auto& [key, value] : parsed->items()) {
    ConfigValue v;
    if (value.is_boolean()) {
      v.kind = ConfigValue::Kind::kBool;
      v.boolean = value.get<bool>();
    } else if (value.is_number_integer() && value.is_number_unsigned()) {
      uint64_t u = value.get<uint64_t>();
      v.number = static_cast<double>(u);
      if (u <= static_cast<uint64_t>(std::numeric_limits<int64_t>::max())) {
        v.kind = ConfigValue::Kind::kInteger;
        v.integer = static_cast<int64_t>(u);
      } else {
        v.kind = ConfigValue::Kind::kNumber;
      }
    } else if (value.is_number_integer()) {
      v.kind = ConfigValue::Kind::kInteger;
      v.integer = value.get<int64_t>();
      v.number = static_cast<double>(v.integer);
    } else if (value.is_number_float()) {
      v.kind = ConfigValue::Kind::kNumber;
      v.number = value.get<double>();
    } else if (value.is_string()) {
      v.kind = ConfigValue::Kind::kString;
      v.string = value.get<std::string>();
    } else {
      return invalid_argument(origin + ": setting '" + echo(key) +
                              "' must be a boolean, number or string (got " +
                              detail::type_name(value) + ")");
    }
    out[key] = std::move(v);
  }
  return out;
}

Result<std::map<std::string, ConfigValue>> read_config_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return invalid_argument("config file " + path + " cannot be read");
  std::string text;
  text.resize(kMaxConfigFileBytes + 1);
  f.read(text.data(), static_cast<std::streamsize>(text.size()));
  if (f.bad()) return invalid_argument("config file " + path + " cannot be read");
  text.resize(static_cast<size_t>(f.gcount()));
  if (text.size() > kMaxConfigFileBytes) {
    return invalid_argument("config file " + path + " is over " +
                            std::to_string(kMaxConfigFileBytes) + " bytes");
  }
  return parse_config_text(text, "config file " + path);
}

}  // namespace grotto::proto
