// The optional shared secret of a deployment (PROTOCOL.md, hello.token): how grotto-server and
// grotto-load read it (a file or the GROTTO_TOKEN environment variable), what a valid token is,
// and how the server compares it. Tokens never appear in logs or error messages.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include "common/core/result.hpp"

namespace grotto::proto {

inline constexpr std::size_t kMaxTokenBytes = 256;  // hello.token
inline constexpr const char* kTokenEnvVariable = "GROTTO_TOKEN";

// A valid token: 1..kMaxTokenBytes bytes of printable ASCII (0x20-0x7e). The message says what
// is wrong without quoting the token.
Status check_token(std::string_view token);

// The token a program runs with: the first line of `token_file`, trimmed of spaces, tabs and
// the line ending, when `token_file` is not empty; else `env_value` (the value of GROTTO_TOKEN;
// null or empty: none). Returns "" when neither gives one. Errors name the setting ("token-file
// PATH: ..." or "GROTTO_TOKEN: ..."): an unreadable file, an empty first line, an invalid token.
Result<std::string> resolve_token(const std::string& token_file, const char* env_value);

// Whether `given` equals `expected`, in a time that depends only on given's length (not on
// where the first difference is).
bool token_equals(std::string_view expected, std::string_view given);

}  // namespace grotto::proto
