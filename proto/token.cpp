#include "proto/token.hpp"

#include <fstream>

namespace grotto::proto {

Status check_token(std::string_view token) {
  if (token.empty()) return invalid_argument("must not be empty");
  if (token.size() > kMaxTokenBytes) {
    return invalid_argument("must be at most " + std::to_string(kMaxTokenBytes) + " bytes (got " +
                            std::to_string(token.size()) + ")");
  }
  for (char c : token) {
    if (c < 0x20 || c > 0x7e) {
      return invalid_argument("must be printable ASCII (found byte " +
                              std::to_string(static_cast<unsigned char>(c)) + ")");
    }
  }
  return {};
}

Result<std::string> resolve_token(const std::string& token_file, const char* env_value) {
  std::string token;
  std::string setting;
  if (!token_file.empty()) {
    setting = "token-file " + token_file;
    std::ifstream in(token_file, std::ios::binary);
    if (!in) return invalid_argument(setting + ": cannot be read");
    std::getline(in, token);
    if (in.bad()) return invalid_argument(setting + ": cannot be read");
    const char* blank = " \t\r\n";
    size_t first = token.find_first_not_of(blank);
    token = first == std::string::npos
                ? std::string()
                : token.substr(first, token.find_last_not_of(blank) - first + 1);
    if (token.empty()) return invalid_argument(setting + ": the first line is empty");
  } else if (env_value != nullptr && *env_value != '\0') {
    setting = kTokenEnvVariable;
    token = env_value;
  } else {
    return std::string();
  }
  if (Status s = check_token(token); !s) {
    return invalid_argument(setting + ": the token " + s.error().message);
  }
  return token;
}

bool token_equals(std::string_view expected, std::string_view given) {
  // Every byte of `given` is looked at whatever matches; an empty `expected` never matches.
  unsigned diff = expected.size() == given.size() && !expected.empty() ? 0u : 1u;
  for (size_t i = 0; i < given.size(); ++i) {
    char e = expected.empty() ? '\0' : expected[i % expected.size()];
    diff |= static_cast<unsigned char>(e ^ given[i]);
  }
  return diff == 0;
}

}  // namespace grotto::proto
