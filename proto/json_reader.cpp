#include "proto/json_reader.hpp"

#include <cmath>

#include "proto/messages.hpp"

namespace grotto::proto::detail {
namespace {

// nlohmann's DOM parser says only "discarded" when exceptions are off; on that (rare) path a
// second pass through its SAX interface recovers the position and reason without throwing.
class ErrorFinder : public nlohmann::json_sax<json> {
 public:
  bool null() override { return true; }
  bool boolean(bool) override { return true; }
  bool number_integer(number_integer_t) override { return true; }
  bool number_unsigned(number_unsigned_t) override { return true; }
  bool number_float(number_float_t, const string_t&) override { return true; }
  bool string(string_t&) override { return true; }
  bool binary(binary_t&) override { return true; }
  bool start_object(std::size_t) override { return true; }
  bool key(string_t&) override { return true; }
  bool end_object() override { return true; }
  bool start_array(std::size_t) override { return true; }
  bool end_array() override { return true; }
  bool parse_error(std::size_t position, const std::string&,
                   const nlohmann::detail::exception& ex) override {
    position_ = position;
    reason_ = ex.what();
    return false;
  }

  std::size_t position_ = 0;
  std::string reason_;
};

// "[json.exception.parse_error.101] parse error at line 1, column 5: syntax error while parsing
// value - invalid literal; last read: 'tru,'" -> "syntax error while parsing value - invalid
// literal". The "last read" part would echo untrusted bytes, so it goes.
std::string short_reason(std::string reason) {
  if (std::size_t cut = reason.find("; last read"); cut != std::string::npos) reason.resize(cut);
  if (reason.starts_with("[json.exception.")) {
    if (std::size_t close = reason.find("] "); close != std::string::npos) {
      reason = reason.substr(close + 2);
    }
  }
  if (reason.starts_with("parse error")) {
    if (std::size_t colon = reason.find(": "); colon != std::string::npos) {
      reason = reason.substr(colon + 2);
    }
  }
  // What is left may still quote a token ("number overflow parsing '1e400'", the whole token
  // however long): the quote goes through echo(), so it is at most kMaxEchoBytes like every
  // other quote in an error message.
  if (std::size_t open = reason.find('\''); open != std::string::npos) {
    std::size_t close = reason.rfind('\'');
    if (close == open) close = reason.size();
    std::string tail = close < reason.size() ? reason.substr(close) : std::string("'");
    reason = reason.substr(0, open + 1) +
             echo(std::string_view(reason).substr(open + 1, close - open - 1)) + tail;
  }
  // Bounded and printable whatever else nlohmann says.
  if (reason.size() > 120) reason = reason.substr(0, 120) + "...";
  for (char& c : reason) {
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) c = '?';
  }
  return reason;
}

// Brackets outside strings, counted before the parser runs: deep nesting is refused in linear
// time with no recursion and no allocation. On invalid JSON the count may be off, but then the
// parser rejects the text anyway.
Status check_depth(std::string_view text) {
  int depth = 0;
  bool in_string = false, escaped = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    char c = text[i];
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonDepth) {
        return Error{ErrorCode::kBadJson, "JSON nested deeper than " +
                                              std::to_string(kMaxJsonDepth) + " levels (byte " +
                                              std::to_string(i) + ")"};
      }
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return {};
}

}  // namespace

Result<json> parse_object(std::string_view text, std::size_t max_bytes) {
  if (text.size() > max_bytes) {
    return Error{ErrorCode::kTooLarge, "message of " + std::to_string(text.size()) +
                                           " bytes exceeds max_message_bytes " +
                                           std::to_string(max_bytes)};
  }
  if (Status depth = check_depth(text); !depth) return depth.error();
  json value = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (value.is_discarded()) {
    ErrorFinder finder;
    json::sax_parse(text, &finder);
    return Error{ErrorCode::kBadJson, "not valid JSON at byte " + std::to_string(finder.position_) +
                                          ": " + short_reason(finder.reason_)};
  }
  if (!value.is_object()) {
    return Error{ErrorCode::kBadMessage,
                 std::string("a message must be a JSON object (got ") + type_name(value) + ")"};
  }
  return value;
}

Error field_error(std::string_view field, std::string_view problem) {
  return Error{ErrorCode::kBadMessage,
               "field '" + std::string(field) + "' " + std::string(problem)};
}

const char* type_name(const json& value) {
  if (value.is_number_integer()) return "integer";
  if (value.is_number_float()) return "float";
  return value.type_name();
}

Result<uint64_t> to_uint(const json& value, std::string_view field, uint64_t max, uint64_t min) {
  if (!value.is_number_integer()) {
    return field_error(field, std::string("must be an integer (got ") + type_name(value) + ")");
  }
  const std::string range = "must be in [" + std::to_string(min) + ", " + std::to_string(max) + "]";
  // nlohmann stores "-0" as a signed integer; only a negative value is out of range.
  if (!value.is_number_unsigned() && value.get<int64_t>() < 0) {
    return field_error(field, range + " (got " + std::to_string(value.get<int64_t>()) + ")");
  }
  uint64_t v = value.is_number_unsigned() ? value.get<uint64_t>()
                                          : static_cast<uint64_t>(value.get<int64_t>());
  if (v < min || v > max) return field_error(field, range + " (got " + std::to_string(v) + ")");
  return v;
}

Result<double> to_number(const json& value, std::string_view field) {
  if (!value.is_number()) {
    return field_error(field, std::string("must be a number (got ") + type_name(value) + ")");
  }
  double v = value.get<double>();
  // JSON cannot spell NaN or infinity, but 1e400 parses to infinity.
  if (!std::isfinite(v)) return field_error(field, "must be finite");
  return v;
}

const json* Fields::find(std::string_view key) const {
  auto it = object_.find(key);
  return it == object_.end() ? nullptr : &*it;
}

Result<uint64_t> Fields::uint(std::string_view key, uint64_t max, uint64_t min) const {
  const json* v = find(key);
  if (!v) return field_error(key, "is missing");
  return to_uint(*v, key, max, min);
}

Result<std::optional<uint64_t>> Fields::optional_uint(std::string_view key, uint64_t max) const {
  const json* v = find(key);
  if (!v) return std::optional<uint64_t>();
  Result<uint64_t> r = to_uint(*v, key, max);
  if (!r) return r.error();
  return std::optional<uint64_t>(*r);
}

Result<double> Fields::number(std::string_view key) const {
  const json* v = find(key);
  if (!v) return field_error(key, "is missing");
  return to_number(*v, key);
}

Result<std::string> Fields::string(std::string_view key, std::size_t max_bytes) const {
  const json* v = find(key);
  if (!v) return field_error(key, "is missing");
  if (!v->is_string()) {
    return field_error(key, std::string("must be a string (got ") + type_name(*v) + ")");
  }
  const std::string& s = v->get_ref<const std::string&>();
  if (s.size() > max_bytes) {
    return Error{ErrorCode::kTooLarge, "field '" + std::string(key) + "' is " +
                                           std::to_string(s.size()) + " bytes, over the limit of " +
                                           std::to_string(max_bytes)};
  }
  return s;
}

Result<std::optional<std::string>> Fields::optional_string(std::string_view key,
                                                           std::size_t max_bytes) const {
  if (!find(key)) return std::optional<std::string>();
  Result<std::string> r = string(key, max_bytes);
  if (!r) return r.error();
  return std::optional<std::string>(std::move(r).value());
}

Result<bool> Fields::boolean(std::string_view key) const {
  const json* v = find(key);
  if (!v) return field_error(key, "is missing");
  if (!v->is_boolean()) {
    return field_error(key, std::string("must be true or false (got ") + type_name(*v) + ")");
  }
  return v->get<bool>();
}

Result<Vec3> Fields::point(std::string_view key) const {
  const json* v = find(key);
  if (!v) return field_error(key, "is missing");
  if (!v->is_array() || v->size() != 3) {
    return field_error(key, "must be an array of 3 numbers [x, y, z]");
  }
  double c[3];
  for (int i = 0; i < 3; ++i) {
    std::string name = std::string(key) + "[" + std::to_string(i) + "]";
    Result<double> r = to_number((*v)[i], name);
    if (!r) return r.error();
    if (std::fabs(*r) > kMaxCoordinate) {
      return field_error(name, "must be within [-16777216, 16777216] metres");
    }
    c[i] = *r;
  }
  return Vec3{c[0], c[1], c[2]};
}

Result<const json*> Fields::array(std::string_view key, std::size_t min, std::size_t max) const {
  const json* v = find(key);
  if (!v) return field_error(key, "is missing");
  if (!v->is_array()) {
    return field_error(key, std::string("must be an array (got ") + type_name(*v) + ")");
  }
  if (v->size() > max) {
    return Error{ErrorCode::kTooLarge, "field '" + std::string(key) + "' has " +
                                           std::to_string(v->size()) +
                                           " entries, over the limit of " + std::to_string(max)};
  }
  if (v->size() < min) {
    return field_error(
        key, min == 1 ? "must not be empty" : "needs at least " + std::to_string(min) + " entries");
  }
  return v;
}

Result<const json*> Fields::object(std::string_view key) const {
  const json* v = find(key);
  if (!v) return field_error(key, "is missing");
  if (!v->is_object()) {
    return field_error(key, std::string("must be an object (got ") + type_name(*v) + ")");
  }
  return v;
}

}  // namespace grotto::proto::detail
