// Internal to grotto::proto (not installed with the public headers' contracts): the hardened
// entry into nlohmann::json and typed field readers that turn every mismatch into a wire error
// naming the field. Shared by messages.cpp and its tests' helpers only.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "common/core/result.hpp"
#include "common/core/vec3.hpp"

namespace grotto::proto::detail {

using nlohmann::json;

// Size limit, nesting pre-scan, then json::parse(text, nullptr, false). The value is an object.
Result<json> parse_object(std::string_view text, std::size_t max_bytes);

// Readers for one field of an object. `name` is the field's path for messages ("rooms[3].lod").
// A missing required field, a wrong JSON type or a value out of range is kBadMessage; a string
// over its cap is kTooLarge.
class Fields {
 public:
  explicit Fields(const json& object) : object_(object) {}

  const json* find(std::string_view key) const;
  Result<uint64_t> uint(std::string_view key, uint64_t max, uint64_t min = 0) const;
  Result<std::optional<uint64_t>> optional_uint(std::string_view key, uint64_t max) const;
  Result<double> number(std::string_view key) const;
  Result<std::string> string(std::string_view key, std::size_t max_bytes) const;
  Result<std::optional<std::string>> optional_string(std::string_view key,
                                                     std::size_t max_bytes) const;
  Result<bool> boolean(std::string_view key) const;
  Result<Vec3> point(std::string_view key) const;
  Result<const json*> array(std::string_view key, std::size_t min, std::size_t max) const;
  Result<const json*> object(std::string_view key) const;

 private:
  const json& object_;
};

Error field_error(std::string_view field, std::string_view problem);
const char* type_name(const json& value);
// An integer in [min, max]; out of range names the range ("must be in [1, 65535] (got 0)").
Result<uint64_t> to_uint(const json& value, std::string_view field, uint64_t max, uint64_t min = 0);
Result<double> to_number(const json& value, std::string_view field);

}  // namespace grotto::proto::detail
