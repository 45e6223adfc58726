// rpyfmm — the rules every file output follows (docs/safety-files.md):
//
//  * a target that exists and is not a regular file (directory, symbolic link, device,
//    FIFO, socket) is refused, never replaced;
//  * temporaries get an unpredictable name next to the target and are created with
//    O_CREAT | O_EXCL | O_NOFOLLOW, so a planted file or link is never opened;
//  * an output that is the same file as an input, or as another output of the same
//    command or run, is refused before any work is done;
//  * appended files are identified by a hash of their content (Fnv1a), so a restart
//    touches only the files its checkpoint wrote.
//
// POSIX only. All failures throw rpyfmm::Error with a message naming the path.
#pragma once

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <random>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "rpyfmm/core/error.hpp"

namespace rpyfmm {

/// A file named on a command line or in a config: the option that named it and its path.
/// An empty path means "not given" and is skipped by the checks.
struct NamedPath {
  std::string option;
  std::filesystem::path path;
};

namespace file_safety_detail {

inline std::string quoted(const std::filesystem::path& path) {
  // Appended, not "'" + path.string(): GCC 12 warns (-Wrestrict) on that form's inlined insert.
  std::string text(1, '\'');
  text += path.string();
  text += '\'';
  return text;
}

inline const char* kind_of(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISLNK(mode)) return "a symbolic link";
  if (S_ISCHR(mode) || S_ISBLK(mode)) return "a device";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

// What a path names, for comparing paths: device and inode when it exists, otherwise its
// absolute, normalised path with symbolic links in the existing part resolved.
struct Identity {
  bool exists = false;
  dev_t device = 0;
  ino_t inode = 0;
  std::filesystem::path canonical;
  bool operator==(const Identity& o) const {
    if (exists != o.exists) return false;
    return exists ? device == o.device && inode == o.inode : canonical == o.canonical;
  }
};

inline Identity identity(const std::filesystem::path& path) {
  Identity id;
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    id.exists = true;
    id.device = st.st_dev;
    id.inode = st.st_ino;
    return id;
  }
  std::error_code ec;
  id.canonical = std::filesystem::weakly_canonical(std::filesystem::absolute(path, ec), ec);
  if (ec) id.canonical = std::filesystem::absolute(path).lexically_normal();
  return id;
}

}  // namespace file_safety_detail

/// Whether `a` and `b` name the same file: same device and inode where both exist, same
/// canonical path where neither exists yet.
inline bool same_file(const std::filesystem::path& a, const std::filesystem::path& b) {
  return file_safety_detail::identity(a) == file_safety_detail::identity(b);
}

/// Throws invalid_argument when an output names the same file as an input or as an
/// earlier output; the message names both options and the path. Run it before any work.
inline void require_distinct_files(std::span<const NamedPath> inputs, std::span<const NamedPath> outputs) {
  using file_safety_detail::identity;
  std::vector<std::pair<const NamedPath*, file_safety_detail::Identity>> seen;
  for (const NamedPath& in : inputs)
    if (!in.path.empty()) seen.emplace_back(&in, identity(in.path));
  const std::size_t input_count = seen.size();
  for (const NamedPath& out : outputs) {
    if (out.path.empty()) continue;
    const auto id = identity(out.path);
    for (std::size_t k = 0; k < seen.size(); ++k) {
      if (!(seen[k].second == id)) continue;
      const bool input = k < input_count;
      throw Error(ErrorCode::invalid_argument,
                  out.option + ": " + file_safety_detail::quoted(out.path) + " is the same file as " +
                      seen[k].first->option + " " + file_safety_detail::quoted(seen[k].first->path) +
                      (input ? " (an output must not replace an input)" : " (two outputs cannot share one file)"));
    }
    seen.emplace_back(&out, id);
  }
}

/// Throws io_error when `path` exists and is not a regular file (a symbolic link counts as
/// not regular: it is refused, not followed). A missing path is fine.
inline void require_regular_or_absent(const std::filesystem::path& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return;
    throw Error(ErrorCode::io_error,
                "cannot inspect " + file_safety_detail::quoted(path) + ": " + std::strerror(errno));
  }
  if (!S_ISREG(st.st_mode))
    throw Error(ErrorCode::io_error, file_safety_detail::quoted(path) + " exists and is " +
                                         file_safety_detail::kind_of(st.st_mode) +
                                         ", not a regular file: refusing to replace it");
}

/// Throws io_error naming `where` when `path` exists and is not a regular file once symbolic links
/// are followed: a directory, or a device, FIFO or socket, whose reads may never end (/dev/zero)
/// or wait forever (a FIFO with no writer). A missing path is left to the reader's own message.
inline void require_regular_input(const std::filesystem::path& path, std::string_view where) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || S_ISREG(st.st_mode)) return;
  throw Error(ErrorCode::io_error, std::string(where) + ": " + file_safety_detail::quoted(path) + " is " +
                                       file_safety_detail::kind_of(st.st_mode) + ", expected a regular file");
}

/// An unpredictable name for a temporary next to `target`: "<name>.tmp.<16 random hex digits>"
/// (nothing can be planted there in advance). Create it with O_CREAT | O_EXCL and try another
/// name when it exists.
inline std::filesystem::path temporary_name_next_to(const std::filesystem::path& target) {
  std::random_device entropy;
  const char* hex = "0123456789abcdef";
  std::string suffix = ".tmp.";
  for (int i = 0; i < 16; ++i) suffix += hex[entropy() & 15u];
  std::filesystem::path temporary = target;
  temporary += suffix;
  return temporary;
}

/// Creates a new, empty temporary file next to `target` (temporary_name_next_to, mode 0666
/// less the umask) with O_CREAT | O_EXCL | O_NOFOLLOW. Returns its descriptor and sets
/// `temporary` to its path.
inline int create_temporary_next_to(const std::filesystem::path& target, std::filesystem::path& temporary) {
  for (int attempt = 0; attempt < 64; ++attempt) {
    temporary = temporary_name_next_to(target);
    const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
    if (fd >= 0) return fd;
    if (errno != EEXIST)
      throw Error(ErrorCode::io_error, "cannot create a temporary file for " + file_safety_detail::quoted(target) +
                                           ": " + std::strerror(errno));
  }
  throw Error(ErrorCode::io_error, "cannot create a temporary file for " + file_safety_detail::quoted(target));
}

/// Writes all of `bytes` to `fd`; throws io_error naming `path` (disk full, ...).
inline void write_all(int fd, std::string_view bytes, const std::filesystem::path& path) {
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd, bytes.data(), bytes.size());
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      throw Error(ErrorCode::io_error,
                  "writing " + file_safety_detail::quoted(path) + " failed: " + std::strerror(n < 0 ? errno : EIO));
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
}

/// Renames `temporary` over `target` after checking again that `target` is a regular file or
/// absent; then syncs the directory so the new name survives a crash.
inline void replace_with(const std::filesystem::path& temporary, const std::filesystem::path& target) {
  require_regular_or_absent(target);
  if (::rename(temporary.c_str(), target.c_str()) != 0)
    throw Error(ErrorCode::io_error, "cannot rename " + file_safety_detail::quoted(temporary) + " to " +
                                         file_safety_detail::quoted(target) + ": " + std::strerror(errno));
  const std::filesystem::path dir = target.has_parent_path() ? target.parent_path() : std::filesystem::path(".");
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    (void)::fsync(dfd);  // best effort: some file systems refuse fsync on directories
    ::close(dfd);
  }
}

/// 64-bit FNV-1a of a byte stream, fed piece by piece: identifies a file's content (an
/// appended output up to a recorded length, a checkpoint's payload).
class Fnv1a {
 public:
  Fnv1a() = default;
  /// Continues a hash whose value so far is `state` (FNV-1a's whole state is its value).
  explicit Fnv1a(std::uint64_t state) : h_(state) {}
  void add(std::string_view bytes) {
    for (unsigned char c : bytes) {
      h_ ^= c;
      h_ *= 1099511628211ull;
    }
  }
  [[nodiscard]] std::uint64_t value() const { return h_; }

 private:
  std::uint64_t h_ = 1469598103934665603ull;
};

}  // namespace rpyfmm
