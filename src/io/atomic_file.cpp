#include "gshaptics/io/atomic_file.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>

#include "gshaptics/error.h"

namespace gshaptics {

void write_file_atomically(const std::string& path, std::initializer_list<std::string_view> parts) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw file_error(path, "cannot open '" + tmp + "' for writing");
    errno = 0;
    for (std::string_view p : parts) out.write(p.data(), std::streamsize(p.size()));
    out.flush();
    const int err = errno;
    if (out) out.close();
    if (!out) {
      std::remove(tmp.c_str());
      throw file_error(path, std::string("write failed (") + (err ? std::strerror(err) : "stream error") +
                                 "); nothing was written");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::remove(tmp.c_str());
    throw file_error(path, "cannot rename the temporary file: " + ec.message());
  }
}

}  // namespace gshaptics
