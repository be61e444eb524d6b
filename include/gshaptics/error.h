#pragma once
/// @file
/// Errors raised at the edges of the library (files, configuration, command line).
/// The servo-tick code never throws; it returns status values instead.

#include <cstdint>
#include <stdexcept>
#include <string>

namespace gshaptics {

/// An error in input the user gave us: a scene file, a registration file, an argument.
/// The message always names the source (file path or option) and what was expected.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& what) : std::runtime_error(what) {}
};

/// Builds the message "<path>: <what>" used by every file reader.
[[nodiscard]] InputError file_error(const std::string& path, const std::string& what);

/// Builds the message "<path>: at byte offset <offset>: <what>".
[[nodiscard]] InputError file_error_at(const std::string& path, std::uint64_t offset,
                                       const std::string& what);

}  // namespace gshaptics
