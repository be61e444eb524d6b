#pragma once
/// @file
/// Writing an output file so that a failure never leaves a half-written file behind.

#include <initializer_list>
#include <string>
#include <string_view>

namespace gshaptics {

/// Writes the concatenation of `parts` to `path` atomically: to `path + ".tmp"` first, then a
/// rename over `path`. On any failure the temporary file is removed and `path` is untouched.
/// Throws InputError naming `path` (cannot open, write failed, e.g. disk full, cannot rename).
void write_file_atomically(const std::string& path, std::initializer_list<std::string_view> parts);

/// Same, for one piece of text.
inline void write_file_atomically(const std::string& path, std::string_view text) {
  write_file_atomically(path, {text});
}

}  // namespace gshaptics
