// rpyfmm CLI — the .npy files of `rigid` and `rigid-bd` across MPI ranks (body_io.hpp).
#include "body_io.hpp"

#include <unistd.h>

#include <climits>
#include <cstdint>
#include <utility>

#include "array_io.hpp"
#include "cli_common.hpp"
#include "npy_collective_io.hpp"
#include "rank_shares.hpp"
#include "rpyfmm/core/atomic_file.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {
namespace {

// Rank 0's body offsets of --body-sizes for the n beads of --positions, on every rank with their
// cuts. The shares' counts and displacements are MPI ints: 3 per bead and 7 per body must fit.
BodyLayout read_layout(const std::string& path, std::size_t n, const mpi::Communicator& comm) {
  std::vector<std::size_t> offsets;
  comm.run([&] {
    if (comm.rank() != 0) return;
    offsets = read_body_offsets(path, n);
    require(3 * n <= static_cast<std::size_t>(INT_MAX) && 7 * (offsets.size() - 1) <= static_cast<std::size_t>(INT_MAX),
            ErrorCode::not_supported, "rpyfmm",
            std::to_string(n) + " beads: more than MPI's int counts address in one scatter");
  });
  return broadcast_body_layout(offsets, comm);
}

}  // namespace

std::size_t first_of_rows(const BodyLayout& z, int per, bool by_beads, int rank) {
  const std::uint64_t body = z.cuts[static_cast<std::size_t>(rank)];
  return static_cast<std::size_t>(per) * static_cast<std::size_t>(by_beads ? z.offsets[body] : body);
}

ArrayShare read_body_rows(const std::string& path, IoMode mode, int per, bool by_beads,
                          const std::function<void(const std::vector<std::size_t>&)>& check,
                          const std::function<std::size_t(const std::vector<std::size_t>&)>& skip,
                          const BodiesShare& bodies, double& scatter_seconds, const mpi::Communicator& comm) {
  const auto in_bodies = [&](const std::vector<std::size_t>& shape) {
    Shares shares = body_shares(bodies.z, per, by_beads);
    const std::size_t whole = static_cast<std::size_t>(shares.displs.back()) + shares.count(comm.size() - 1);
    const std::size_t offset = skip ? skip(shape) : 0;
    comm.run([&] {
      require(offset + whole <= static_cast<std::size_t>(INT_MAX), ErrorCode::not_supported, path,
              "more values than MPI's int counts address in one scatter");
    });
    for (int& displ : shares.displs) displ += static_cast<int>(offset);
    return shares;
  };
  return read_share_in(path, mode, check, in_bodies, scatter_seconds, comm);
}

BodiesShare read_bodies_share(const BeadBodyArgs& args, IoMode mode, const mpi::Communicator& comm) {
  comm.run([&] { require_one_radius(args); });
  BodiesShare b;
  std::size_t n = 0;
  const auto in_bodies = [&](const std::vector<std::size_t>& shape) {
    n = values_of(shape) / 3;
    b.z = read_layout(args.body_sizes, n, comm);
    return body_shares(b.z, 3, true);
  };
  ArrayShare x = read_share_in(
      args.positions, mode, [](const auto& shape) { require_points_shape(shape, "positions"); }, in_bodies,
      b.scatter_seconds, comm);
  require_finite_entries(x, "positions", 3, comm);
  b.local.x = std::move(x.local);
  b.local.offsets = local_body_offsets(b.z, comm.rank());
  if (args.radius_given) {
    b.local.radii.assign(b.local.offsets.back(), args.radius);
  } else {
    ArrayShare radii = read_body_rows(
        args.radii, mode, 1, true, [n](const auto& shape) { require_vector_shape(shape, n, "radii"); }, {}, b,
        b.scatter_seconds, comm);
    require_finite_entries(radii, "radii", 1, comm);
    b.local.radii = std::move(radii.local);
  }
  if (!args.reference.empty()) {
    const std::size_t m = b.z.bodies();
    const auto check = [m](const std::vector<std::size_t>& shape) {
      require_points_shape(shape, "reference points");
      require(
          values_of(shape) == 3 * m, ErrorCode::invalid_input, "--reference",
          "has " + std::to_string(values_of(shape) / 3) + " rows, expected " + std::to_string(m) + " (one per body)");
    };
    ArrayShare reference = read_body_rows(args.reference, mode, 3, false, check, {}, b, b.scatter_seconds, comm);
    require_finite_entries(reference, "reference points", 3, comm);
    b.local.reference = std::move(reference.local);
    b.reference = true;
  }
  return b;
}

void require_finite_result(std::span<const NpyRun> runs, const std::string& what, const mpi::Communicator& comm) {
  require_finite_runs(
      runs, [&](std::size_t i, bool nan) { return nonfinite_output(i, nan, what); }, comm);
}

namespace {

// Collective: `file` in its temporary next to its path, written and synced; the temporary's name on
// rank 0 (with --io collective on every rank).
std::string rows_temporary(const RowsFile& file, IoMode mode, const mpi::Communicator& comm) {
  if (mode == IoMode::collective) return write_npy_temporary_at_all(file.path, file.shape, file.runs, comm);
  std::vector<double> whole(comm.rank() == 0 ? file.runs.size() * file.block : 0);
  comm.run([&] {
    for (std::size_t j = 0; j < file.runs.size(); ++j) {
      const std::vector<double> local(file.runs[j].values.begin(), file.runs[j].values.end());
      gather(local, file.shares, comm.rank() == 0 ? whole.data() + j * file.block : nullptr, comm);
    }
  });
  std::string tmp;
  comm.run([&] {
    if (comm.rank() == 0) tmp = write_temporary_next_to(file.path, npy_writer(file.shape, whole)).string();
  });
  return tmp;
}

}  // namespace

void write_rows_together(std::span<const RowsFile> files, IoMode mode, const mpi::Communicator& comm) {
  std::vector<std::string> temporaries;  // rank 0's to rename; cleared once renamed
  try {
    for (const RowsFile& file : files) temporaries.push_back(rows_temporary(file, mode, comm));
    comm.run([&] {
      if (comm.rank() != 0) return;
      for (std::size_t i = 0; i < files.size(); ++i) {
        replace_with(temporaries[i], files[i].path);
        temporaries[i].clear();
      }
    });
  } catch (...) {
    if (comm.rank() == 0)
      for (const std::string& tmp : temporaries)
        if (!tmp.empty()) ::unlink(tmp.c_str());
    throw;
  }
}

}  // namespace rpyfmm::cli
