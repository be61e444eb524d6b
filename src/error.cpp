#include "gshaptics/error.h"

namespace gshaptics {

InputError file_error(const std::string& path, const std::string& what) {
  return InputError(path + ": " + what);
}

InputError file_error_at(const std::string& path, std::uint64_t offset, const std::string& what) {
  return InputError(path + ": at byte offset " + std::to_string(offset) + ": " + what);
}

}  // namespace gshaptics
