// rpyfmm CLI — .npy files read and written by every rank with MPI-IO (npy_collective_io.hpp).
#include "npy_collective_io.hpp"

#include <mpi.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <climits>
#include <cstdint>
#include <cstring>
#include <functional>

#include "rank_shares.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/core/file_safety.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {
namespace {

// The problem of a failed MPI-IO call on `path`: the call and MPI's error string.
std::optional<Error> io_problem(int rc, const char* call, const std::string& path) {
  if (rc == MPI_SUCCESS) return std::nullopt;
  std::array<char, MPI_MAX_ERROR_STRING> text{};
  int length = 0;
  if (MPI_Error_string(rc, text.data(), &length) != MPI_SUCCESS) length = 0;
  return Error(ErrorCode::io_error, "'" + path + "': " + call + " failed: " + std::string(text.data(), length));
}

// {has a layout, item, data offset, shape...}: the layout as broadcast.
std::vector<std::uint64_t> facts_of(const std::optional<NpyLayout>& layout) {
  if (!layout) return {0};
  std::vector<std::uint64_t> facts{1, layout->item, layout->data_offset};
  facts.insert(facts.end(), layout->shape.begin(), layout->shape.end());
  return facts;
}

std::optional<NpyLayout> layout_of(const std::vector<std::uint64_t>& facts) {
  if (facts.at(0) == 0) return std::nullopt;
  NpyLayout layout;
  layout.item = static_cast<std::size_t>(facts[1]);
  layout.data_offset = facts[2];
  layout.shape.assign(facts.begin() + 3, facts.end());
  return layout;
}

// The file opened by every rank with `mode`, or every rank fails naming it. Where the open failed
// on some ranks only, the others' handles are left open: closing is collective and would wait for
// the ranks that failed.
MPI_File open_at_all(const std::string& path, int mode, const mpi::Communicator& comm) {
  MPI_File file = MPI_FILE_NULL;
  const int rc = MPI_File_open(comm.get(), path.c_str(), mode, MPI_INFO_NULL, &file);
  comm.agree(io_problem(rc, "MPI_File_open", path));
  return file;
}

// Closes `file` on every rank; the first problem of this rank (`problem`, then the close) is agreed.
void close_and_agree(MPI_File& file, std::optional<Error> problem, const std::string& path,
                     const mpi::Communicator& comm) {
  const int rc = MPI_File_close(&file);
  if (!problem) problem = io_problem(rc, "MPI_File_close", path);
  comm.agree(problem);
}

// `count` values of `type` at byte `offset` into `buffer`, read by every rank at once; a short read
// (the file shrank after its size was checked) is a problem naming the file.
std::optional<Error> read_at_all(MPI_File file, MPI_Offset offset, void* buffer, std::size_t count, MPI_Datatype type,
                                 const std::string& path) {
  MPI_Status status;
  const int rc = MPI_File_read_at_all(file, offset, buffer, static_cast<int>(count), type, &status);
  if (auto problem = io_problem(rc, "MPI_File_read_at_all", path)) return problem;
  int got = 0;
  MPI_Get_count(&status, type, &got);
  if (static_cast<std::size_t>(got) == count) return std::nullopt;
  return Error(ErrorCode::io_error, "'" + path + "': truncated .npy data: read " + std::to_string(got) + " of " +
                                        std::to_string(count) + " values (did the file change while it was read?)");
}

// Runs `body`; where it throws, rank 0 removes the temporary `tmp` before the error goes on.
void removing_on_failure(const std::string& tmp, const mpi::Communicator& comm, const std::function<void()>& body) {
  try {
    body();
  } catch (...) {
    if (comm.rank() == 0) ::unlink(tmp.c_str());
    throw;
  }
}

// On rank 0: the target checked (write_file_atomically's rules), a new temporary next to it
// holding `header`; returns the temporary's name on every rank.
std::string temporary_with_header(const std::string& path, const std::string& header, const mpi::Communicator& comm) {
  std::string tmp;
  comm.run([&] {
    if (comm.rank() != 0) return;
    require_regular_or_absent(path);
    std::filesystem::path created;
    const int fd = create_temporary_next_to(path, created);
    tmp = created.string();
    try {
      write_all(fd, header, path);
    } catch (...) {
      ::close(fd);
      ::unlink(tmp.c_str());
      throw;
    }
    if (::close(fd) != 0) {
      const std::string reason = std::strerror(errno);
      ::unlink(tmp.c_str());
      throw Error(ErrorCode::io_error, "closing '" + path + "' failed: " + reason);
    }
  });
  std::vector<std::uint64_t> bytes(tmp.begin(), tmp.end());
  broadcast(bytes, comm);
  return std::string(bytes.begin(), bytes.end());
}

// Every rank's runs of values at their offsets after `header_bytes`, written and synced.
void write_values_at_all(const std::string& tmp, const std::string& path, std::size_t header_bytes,
                         std::span<const NpyRun> runs, const mpi::Communicator& comm) {
  MPI_File file = open_at_all(tmp, MPI_MODE_WRONLY, comm);
  std::optional<Error> problem;
  for (const NpyRun& run : runs) {
    MPI_Status status;
    const auto offset = static_cast<MPI_Offset>(header_bytes + run.first * sizeof(double));
    const int rc = MPI_File_write_at_all(file, offset, run.values.data(), static_cast<int>(run.values.size()),
                                         MPI_DOUBLE, &status);
    if (!problem) problem = io_problem(rc, "MPI_File_write_at_all", path);
  }
  const int synced = MPI_File_sync(file);
  if (!problem) problem = io_problem(synced, "MPI_File_sync", path);
  close_and_agree(file, problem, path, comm);
}

}  // namespace

std::optional<NpyLayout> shared_npy_layout(const std::string& path, const mpi::Communicator& comm) {
  std::optional<NpyLayout> layout;
  comm.run([&] {
    if (comm.rank() == 0) layout = npy_file_layout(path);
  });
  std::vector<std::uint64_t> facts = facts_of(layout);
  broadcast(facts, comm);
  return layout_of(facts);
}

std::vector<double> read_values_at_all(const std::string& path, const NpyLayout& layout, std::size_t first,
                                       std::size_t count, const mpi::Communicator& comm) {
  comm.run([&] {
    require(count <= static_cast<std::size_t>(INT_MAX), ErrorCode::not_supported, path,
            "more values per rank than MPI's int counts address in one read");
  });
  MPI_File file = open_at_all(path, MPI_MODE_RDONLY, comm);
  const auto offset = static_cast<MPI_Offset>(layout.data_offset + first * layout.item);
  std::vector<double> values(count);
  std::optional<Error> problem;
  if (layout.item == 8) {
    problem = read_at_all(file, offset, values.data(), count, MPI_DOUBLE, path);
  } else {
    std::vector<float> narrow(count);
    problem = read_at_all(file, offset, narrow.data(), count, MPI_FLOAT, path);
    values.assign(narrow.begin(), narrow.end());
  }
  close_and_agree(file, problem, path, comm);
  return values;
}

void write_npy_at_all(const std::string& path, const std::vector<std::size_t>& shape, std::span<const double> local,
                      std::size_t first, const mpi::Communicator& comm) {
  const NpyRun run{first, local};
  write_npy_at_all(path, shape, std::span<const NpyRun>(&run, 1), comm);
}

std::string write_npy_temporary_at_all(const std::string& path, const std::vector<std::size_t>& shape,
                                       std::span<const NpyRun> runs, const mpi::Communicator& comm) {
  comm.run([&] {
    for (const NpyRun& run : runs)
      require(run.values.size() <= static_cast<std::size_t>(INT_MAX), ErrorCode::not_supported, path,
              "more values per rank than MPI's int counts address in one write");
  });
  const std::string header = npy_header(shape);
  const std::string tmp = temporary_with_header(path, header, comm);
  removing_on_failure(tmp, comm, [&] { write_values_at_all(tmp, path, header.size(), runs, comm); });
  return tmp;
}

void write_npy_at_all(const std::string& path, const std::vector<std::size_t>& shape, std::span<const NpyRun> runs,
                      const mpi::Communicator& comm) {
  const std::string tmp = write_npy_temporary_at_all(path, shape, runs, comm);
  removing_on_failure(tmp, comm, [&] {
    comm.run([&] {
      if (comm.rank() == 0) replace_with(tmp, path);
    });
  });
}

}  // namespace rpyfmm::cli
