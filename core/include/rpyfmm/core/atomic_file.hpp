// rpyfmm — files written so that a failure never leaves a truncated file in place of a
// good one, and never writes anywhere but the named target (file_safety.hpp):
//
//   1. a target that exists and is not a regular file is refused (message names it);
//   2. the data go to a new temporary next to the target, created with an unpredictable
//      name and O_CREAT | O_EXCL | O_NOFOLLOW (no planted file or link is ever opened);
//   3. the temporary is flushed, fsync'ed and closed, then renamed over the target.
//
// On any failure the temporary is removed and the target is left as it was.
#pragma once

#include <array>
#include <filesystem>
#include <functional>
#include <ostream>
#include <streambuf>
#include <string>
#include <vector>

#include "rpyfmm/core/error.hpp"
#include "rpyfmm/core/file_safety.hpp"

namespace rpyfmm {

namespace atomic_file_detail {

// A buffered std::streambuf over a file descriptor; write errors surface as exceptions.
class FdBuffer : public std::streambuf {
 public:
  FdBuffer(int fd, std::filesystem::path path) : fd_(fd), path_(std::move(path)) {
    setp(buffer_.data(), buffer_.data() + buffer_.size());
  }
  void flush_all() {
    write_all(fd_, std::string_view(pbase(), static_cast<std::size_t>(pptr() - pbase())), path_);
    setp(buffer_.data(), buffer_.data() + buffer_.size());
  }

 protected:
  int_type overflow(int_type c) override {
    flush_all();
    if (!traits_type::eq_int_type(c, traits_type::eof())) sputc(traits_type::to_char_type(c));
    return traits_type::not_eof(c);
  }
  int sync() override {
    flush_all();
    return 0;
  }

 private:
  int fd_;
  std::filesystem::path path_;
  std::array<char, 1 << 16> buffer_{};
};

}  // namespace atomic_file_detail

/// Steps 1 and 2 of write_file_atomically: checks `path`, calls `write(stream)` on a new temporary
/// next to it, flushes, fsyncs and closes it; returns the temporary's path (the caller renames it
/// with replace_with or unlinks it). On any failure the temporary is removed and the error thrown.
inline std::filesystem::path write_temporary_next_to(const std::filesystem::path& path,
                                                     const std::function<void(std::ostream&)>& write) {
  require_regular_or_absent(path);
  std::filesystem::path tmp;
  int fd = create_temporary_next_to(path, tmp);
  try {
    atomic_file_detail::FdBuffer buffer(fd, path);
    std::ostream out(&buffer);
    out.exceptions(std::ios::badbit);  // a failed flush inside the stream rethrows its Error
    write(out);
    buffer.flush_all();
    if (::fsync(fd) != 0)
      throw Error(ErrorCode::io_error, "cannot sync '" + path.string() + "' to disk: " + std::strerror(errno));
    const int closed = ::close(fd);
    fd = -1;
    if (closed != 0)
      throw Error(ErrorCode::io_error, "closing '" + path.string() + "' failed: " + std::strerror(errno));
    return tmp;
  } catch (...) {
    if (fd >= 0) ::close(fd);
    ::unlink(tmp.c_str());
    throw;
  }
}

/// Calls `write(stream)` on a temporary file next to `path`, then renames it to `path`
/// (steps above). Throws rpyfmm::Error(io_error) naming the file when the target is not a
/// regular file or any write, sync or rename fails; an exception from `write` is rethrown.
/// `mode` is accepted for source compatibility: POSIX files have no text mode.
inline void write_file_atomically(const std::filesystem::path& path, const std::function<void(std::ostream&)>& write,
                                  [[maybe_unused]] std::ios::openmode mode = std::ios::binary) {
  const std::filesystem::path tmp = write_temporary_next_to(path, write);
  try {
    replace_with(tmp, path);
  } catch (...) {
    ::unlink(tmp.c_str());
    throw;
  }
}

/// One file of write_files_atomically: its path and what writes its content.
struct FileWrite {
  std::filesystem::path path;
  std::function<void(std::ostream&)> write;
};

/// Several files of one result (e.g. a command's two outputs): every one is written to its
/// temporary first (write_temporary_next_to), and only when all are on disk are they renamed over
/// their targets, in order. A failure while writing (missing folder, full disk) leaves every
/// target as it was; only a failing rename, after all data are on disk, can leave the earlier
/// targets replaced. Temporaries are removed on any failure.
inline void write_files_atomically(const std::vector<FileWrite>& files) {
  std::vector<std::filesystem::path> temporaries;
  try {
    for (const FileWrite& f : files) temporaries.push_back(write_temporary_next_to(f.path, f.write));
    for (std::size_t i = 0; i < files.size(); ++i) {
      replace_with(temporaries[i], files[i].path);
      temporaries[i].clear();  // renamed: nothing left to remove
    }
  } catch (...) {
    for (const auto& tmp : temporaries)
      if (!tmp.empty()) ::unlink(tmp.c_str());
    throw;
  }
}

}  // namespace rpyfmm
