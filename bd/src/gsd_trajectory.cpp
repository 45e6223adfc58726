// GSD trajectories through the gsd C library (gsd.h; compiled from the gsd source distribution by
// cmake/RpyfmmGsd.cmake). Builds without it compile gsd_unavailable.cpp instead.
#include "rpyfmm/bd/gsd_trajectory.hpp"

#include <gsd.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <vector>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

static_assert(static_cast<int>(GsdType::uint8) == GSD_TYPE_UINT8 && static_cast<int>(GsdType::int8) == GSD_TYPE_INT8 &&
              static_cast<int>(GsdType::float32) == GSD_TYPE_FLOAT &&
              static_cast<int>(GsdType::float64) == GSD_TYPE_DOUBLE &&
              static_cast<int>(GsdType::character) == GSD_TYPE_CHARACTER);

bool gsd_supported() {
  return true;
}

std::string gsd_unsupported_reason() {
  return {};
}

namespace {

// The header of the files (gsd docs, "HOOMD schema": schema "hoomd", version 1.4).
constexpr const char* kApplication = "rpyfmm";
constexpr const char* kSchema = "hoomd";
constexpr unsigned kSchemaMajor = 1, kSchemaMinor = 4;

std::string gsd_error(int code) {
  switch (code) {
    case GSD_ERROR_IO:
      return std::string("input/output error: ") + std::strerror(errno);
    case GSD_ERROR_NOT_A_GSD_FILE:
      return "not a GSD file";
    case GSD_ERROR_INVALID_GSD_FILE_VERSION:
      return "a GSD file version this gsd library cannot read";
    case GSD_ERROR_FILE_CORRUPT:
      return "the GSD file is corrupt";
    case GSD_ERROR_MEMORY_ALLOCATION_FAILED:
      return "out of memory";
    case GSD_ERROR_NAMELIST_FULL:
      return "too many chunk names";
    default:
      return "gsd error " + std::to_string(code);
  }
}

/// Throws io_error "<doing> '<path>': <gsd's reason>" unless `code` is GSD_SUCCESS.
void check(int code, const char* doing, const std::filesystem::path& path) {
  if (code != GSD_SUCCESS)
    fail(ErrorCode::io_error, "gsd",
         std::string(doing) + " " + file_safety_detail::quoted(path) + ": " + gsd_error(code));
}

/// Adds one frame to `hash`: its chunks in name order, each as name, type, shape and bytes.
void hash_frame(Fnv1a& hash, std::span<const GsdChunk> chunks) {
  std::vector<const GsdChunk*> sorted;
  for (const auto& c : chunks) sorted.push_back(&c);
  std::sort(sorted.begin(), sorted.end(), [](const GsdChunk* a, const GsdChunk* b) { return a->name < b->name; });
  for (const GsdChunk* c : sorted) {
    hash.add(c->name);
    char shape[1 + sizeof c->rows + sizeof c->columns];
    shape[0] = static_cast<char>(c->type);
    std::memcpy(shape + 1, &c->rows, sizeof c->rows);
    std::memcpy(shape + 1 + sizeof c->rows, &c->columns, sizeof c->columns);
    hash.add(std::string_view(shape, sizeof shape));
    hash.add(std::string_view(reinterpret_cast<const char*>(c->data.data()), c->data.size()));
  }
}

}  // namespace

struct GsdTrajectory::Handle {
  gsd_handle h{};
  bool open = false;
  Handle() = default;
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() {
    if (open) (void)gsd_close(&h);
  }
};

namespace {

/// The names of every chunk in `file`, in the order they were first written.
std::vector<std::string> chunk_names(gsd_handle& file) {
  std::vector<std::string> names;
  for (const char* n = gsd_find_matching_chunk_name(&file, "", nullptr); n;
       n = gsd_find_matching_chunk_name(&file, "", n))
    names.emplace_back(n);
  return names;
}

/// The chunks of frame `frame` of `file` (of `file_bytes` bytes, named `path` in errors).
std::vector<GsdChunk> read_frame(gsd_handle& file, std::uint64_t frame, const std::vector<std::string>& names,
                                 std::uint64_t file_bytes, const std::filesystem::path& path) {
  std::vector<GsdChunk> chunks;
  for (const auto& name : names) {
    const gsd_index_entry* e = gsd_find_chunk(&file, frame, name.c_str());
    if (!e) continue;
    const std::uint64_t size = gsd_sizeof_type(static_cast<gsd_type>(e->type));
    if (size == 0 || e->N > file_bytes || e->M > file_bytes || e->N * e->M > file_bytes / size)
      check(GSD_ERROR_FILE_CORRUPT, "reading", path);
    GsdChunk c{name, static_cast<GsdType>(e->type), e->N, e->M, std::vector<std::byte>(e->N * e->M * size)};
    if (!c.data.empty()) check(gsd_read_chunk(&file, c.data.data(), e), "reading", path);
    chunks.push_back(std::move(c));
  }
  return chunks;
}

/// Opens the regular file `path` (lstat'ed as `st`) read-only; refuses a file swapped meanwhile.
void open_to_continue(gsd_handle& h, bool& open, const std::filesystem::path& path, const struct stat& st) {
  const std::string name = file_safety_detail::quoted(path);
  const int rc = gsd_open(&h, path.c_str(), GSD_OPEN_READONLY);
  if (rc != GSD_SUCCESS)
    fail(ErrorCode::io_error, "restart", "cannot open " + name + " to continue it: " + gsd_error(rc));
  open = true;
  struct stat now {};
  if (::fstat(h.fd, &now) != 0 || !S_ISREG(now.st_mode) || now.st_dev != st.st_dev || now.st_ino != st.st_ino)
    fail(ErrorCode::io_error, "restart", name + " changed while it was opened: left untouched");
}

}  // namespace

GsdTrajectory::GsdTrajectory() = default;

GsdTrajectory::~GsdTrajectory() {
  file_.reset();  // gsd_close commits the buffered frames
  if (!temporary_.empty()) ::unlink(temporary_.c_str());
}

bool GsdTrajectory::is_open() const {
  return file_ && file_->open;
}

void GsdTrajectory::open_temporary() {
  for (int attempt = 0; attempt < 64; ++attempt) {
    temporary_ = temporary_name_next_to(path_);
    auto f = std::make_unique<Handle>();
    f->h.fd = -1;
    errno = 0;
    const int rc = gsd_create_and_open(&f->h, temporary_.c_str(), kApplication, kSchema,
                                       gsd_make_version(kSchemaMajor, kSchemaMinor), GSD_OPEN_APPEND, 1);
    if (rc == GSD_SUCCESS) {
      f->open = true;
      file_ = std::move(f);
      return;
    }
    const int error = errno;
    if (rc == GSD_ERROR_IO && error == EEXIST) continue;  // O_EXCL: somebody else's name, try another
    if (f->h.fd >= 0) ::unlink(temporary_.c_str());       // created, then failed: ours to remove
    temporary_.clear();
    errno = error;
    check(rc, "cannot create a temporary file for", path_);
  }
  temporary_.clear();
  fail(ErrorCode::io_error, "gsd", "cannot create a temporary file for " + file_safety_detail::quoted(path_));
}

void GsdTrajectory::create(const std::filesystem::path& path) {
  path_ = path;
  require_regular_or_absent(path);
  open_temporary();
}

void GsdTrajectory::reopen(const std::filesystem::path& path, std::uint64_t keep_frames, std::uint64_t expected_hash) {
  path_ = path;
  const std::string name = file_safety_detail::quoted(path);
  require_regular_or_absent(path);
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0)
    fail(ErrorCode::io_error, "restart", "cannot open " + name + " to continue it: " + std::strerror(errno));
  Handle source;
  open_to_continue(source.h, source.open, path, st);
  if (gsd_get_nframes(&source.h) < keep_frames)
    fail(ErrorCode::io_error, "restart",
         name + " has fewer frames than recorded in the checkpoint (" + std::to_string(keep_frames) +
             "): it does not belong to this checkpoint");
  open_temporary();
  try {
    const auto names = chunk_names(source.h);
    for (std::uint64_t f = 0; f < keep_frames; ++f)
      write(read_frame(source.h, f, names, static_cast<std::uint64_t>(st.st_size), path));
    if (hash_.value() != expected_hash)
      fail(ErrorCode::io_error, "restart",
           name + " does not match the checkpoint (its first " + std::to_string(keep_frames) +
               " frames differ from what the checkpointed run wrote): it belongs to another run; left untouched");
  } catch (...) {
    file_.reset();
    ::unlink(temporary_.c_str());
    temporary_.clear();
    throw;
  }
}

void GsdTrajectory::publish() {
  if (temporary_.empty()) return;
  flush();
  replace_with(temporary_, path_);
  temporary_.clear();
}

void GsdTrajectory::write(std::span<const GsdChunk> chunks) {
  for (const auto& c : chunks)
    check(gsd_write_chunk(&file_->h, c.name.c_str(), static_cast<gsd_type>(c.type), c.rows, c.columns, 0,
                          c.data.empty() ? nullptr : c.data.data()),
          "writing", path_);
  check(gsd_end_frame(&file_->h), "writing", path_);
  hash_frame(hash_, chunks);
  ++frames_;
}

void GsdTrajectory::flush() {
  if (is_open()) check(gsd_flush(&file_->h), "writing", path_);
}

}  // namespace rpyfmm::bd
