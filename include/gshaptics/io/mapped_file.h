#pragma once
/// @file
/// Read-only memory mapping of a whole file, so large scenes load without a second copy.

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

namespace gshaptics {

/// Throws InputError naming `path` when it does not exist or is not a regular file (a FIFO, a
/// folder, a device): reading one would hang or fail obscurely. Stats the path, opens nothing.
void require_regular_file(const std::string& path);

/// A read-only view of a file's bytes, memory-mapped (POSIX mmap). Move-only.
/// Throws InputError naming the file when it cannot be opened, is a directory, or cannot be mapped.
class MappedFile {
 public:
  explicit MappedFile(const std::string& path);
  ~MappedFile();
  MappedFile(MappedFile&& other) noexcept;
  MappedFile& operator=(MappedFile&& other) noexcept;
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;

  /// The file's bytes (empty for an empty file).
  [[nodiscard]] std::span<const std::uint8_t> bytes() const { return {data_, size_}; }
  [[nodiscard]] const std::string& path() const { return path_; }
  /// Tells the kernel the bytes before `offset` will not be read again, so their pages can be
  /// dropped (keeps a sequential load from holding the whole file resident). Later reads of
  /// those bytes still work: the pages come back from the page cache.
  void release_before(std::size_t offset) const noexcept;

 private:
  std::string path_;
  const std::uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace gshaptics
