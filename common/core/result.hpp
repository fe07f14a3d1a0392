// Result<T>: a value or an Error {code, message}. Every boundary where outside data enters
// (network bytes, JSON, files, command-line flags, OpenCL) returns one; exceptions never cross a
// module's public functions.
#pragma once

#include <cassert>
#include <string>
#include <utility>
#include <variant>

namespace grotto {

// Error codes are stable strings on the wire (see proto/PROTOCOL.md); this enum is their C++ face.
enum class ErrorCode {
  kInvalidArgument,  // a value from outside is malformed or out of range
  kNotFound,         // a well-formed reference to something that does not exist
  kUnavailable,      // a resource (device, file, peer) cannot be used right now
  kInternal,         // a broken invariant that was caught instead of crashing
  // Codes that only the wire protocol produces (proto/PROTOCOL.md, "Error codes").
  kBadJson,             // a text frame that is not one JSON object
  kBadMessage,          // a field of the wrong type, out of range, missing, or a duplicate id
  kUnknownType,         // a message type this version does not know
  kUnsupportedVersion,  // no protocol version in common, or a frame of another version
  kTooLarge,            // a frame, string or list over its limit
  kInvalidRoomId,       // a room id that is malformed or out of range (not merely absent)
  kLimitExceeded,       // a per-client limit (rooms in flight, request rate) would be exceeded
  kWorldMismatch,   // the client asked for a world (seed, parameters) this server does not serve
  kOutOfOrder,      // a message that is not valid now (before hello, or hello twice)
  kBadFrame,        // a binary frame that fails validation
  kUnauthorized,    // the deployment requires credentials the client did not give
  kServiceRestart,  // the server is shutting down; reconnect later
  kOverloaded,      // the server cannot take more work now; retry later
  kTimeout,         // no complete message within the handshake or idle timeout
};

const char* error_code_name(ErrorCode code);

struct Error {
  ErrorCode code = ErrorCode::kInternal;
  std::string message;
};

inline Error invalid_argument(std::string message) {
  return {ErrorCode::kInvalidArgument, std::move(message)};
}
inline Error not_found(std::string message) {
  return {ErrorCode::kNotFound, std::move(message)};
}

template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : state_(std::move(value)) {}
  Result(Error error) : state_(std::move(error)) {}

  bool ok() const { return state_.index() == 0; }
  explicit operator bool() const { return ok(); }

  const T& value() const& {
    assert(ok());
    return std::get<0>(state_);
  }
  T& value() & {
    assert(ok());
    return std::get<0>(state_);
  }
  T&& value() && {
    assert(ok());
    return std::get<0>(std::move(state_));
  }
  const T& operator*() const& { return value(); }
  const T* operator->() const { return &value(); }

  const Error& error() const {
    assert(!ok());
    return std::get<1>(state_);
  }

 private:
  std::variant<T, Error> state_;
};

// Result<void>: success or an Error.
class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(Error error) : error_(std::move(error)), ok_(false) {}
  bool ok() const { return ok_; }
  explicit operator bool() const { return ok_; }
  const Error& error() const {
    assert(!ok_);
    return error_;
  }

 private:
  Error error_;
  bool ok_ = true;
};

inline const char* error_code_name(ErrorCode code) {
  switch (code) {
    case ErrorCode::kInvalidArgument:
      return "invalid_argument";
    case ErrorCode::kNotFound:
      return "not_found";
    case ErrorCode::kUnavailable:
      return "unavailable";
    case ErrorCode::kInternal:
      return "internal";
    case ErrorCode::kBadJson:
      return "bad_json";
    case ErrorCode::kBadMessage:
      return "bad_message";
    case ErrorCode::kUnknownType:
      return "unknown_type";
    case ErrorCode::kUnsupportedVersion:
      return "unsupported_version";
    case ErrorCode::kTooLarge:
      return "too_large";
    case ErrorCode::kInvalidRoomId:
      return "invalid_room_id";
    case ErrorCode::kLimitExceeded:
      return "limit_exceeded";
    case ErrorCode::kWorldMismatch:
      return "world_mismatch";
    case ErrorCode::kOutOfOrder:
      return "out_of_order";
    case ErrorCode::kBadFrame:
      return "bad_frame";
    case ErrorCode::kUnauthorized:
      return "unauthorized";
    case ErrorCode::kServiceRestart:
      return "service_restart";
    case ErrorCode::kOverloaded:
      return "overloaded";
    case ErrorCode::kTimeout:
      return "timeout";
  }
  return "internal";
}

}  // namespace grotto
