// rpyfmm CLI — one input array's contiguous shares over the ranks (array_shares.hpp).
#include "array_shares.hpp"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>

#include "array_io.hpp"
#include "npy_collective_io.hpp"
#include "rank_shares.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {
std::vector<std::size_t> read_whole_on_root(const std::string& path, Array& whole, const mpi::Communicator& comm) {
  comm.run([&] {
    if (comm.rank() == 0) whole = read_array(path);
  });
  std::vector<std::uint64_t> shape(whole.shape.begin(), whole.shape.end());
  broadcast(shape, comm);
  return {shape.begin(), shape.end()};
}

ArrayShare read_points_share(const std::string& path, const std::string& name, IoMode mode, double& scatter_seconds,
                             const mpi::Communicator& comm) {
  ArrayShare points = read_share(
      path, mode, 3, [&](const auto& shape) { require_points_shape(shape, name); }, scatter_seconds, comm);
  require_finite_entries(points, name, 3, comm);
  return points;
}

void require_finite_entries(const ArrayShare& share, const std::string& name, std::size_t stride,
                            const mpi::Communicator& comm) {
  require_finite_share(
      share.local, share.first,
      [&](std::size_t i, bool nan) {
        return Error(ErrorCode::invalid_input, name + " " + nonfinite_entry(i, stride, nan));
      },
      comm);
}

IoMode io_mode(const std::string& name) {
  if (name == "root") return IoMode::root;
  require(name == "collective", ErrorCode::invalid_argument, "--io", "expected root or collective, got '" + name + "'");
  return IoMode::collective;
}

std::size_t values_of(const std::vector<std::size_t>& shape) {
  std::size_t count = 1;
  for (std::size_t s : shape) count *= s;
  return count;
}

ArrayShare read_share(const std::string& path, IoMode mode, int per,
                      const std::function<void(const std::vector<std::size_t>&)>& check, double& scatter_seconds,
                      const mpi::Communicator& comm) {
  const auto balanced = [&](const std::vector<std::size_t>& shape) {
    Shares shares;
    comm.run([&] { shares = shares_of(values_of(shape) / static_cast<std::size_t>(per), comm.size(), per); });
    return shares;
  };
  return read_share_in(path, mode, check, balanced, scatter_seconds, comm);
}

ArrayShare read_share_in(const std::string& path, IoMode mode,
                         const std::function<void(const std::vector<std::size_t>&)>& check,
                         const std::function<Shares(const std::vector<std::size_t>&)>& shares_for,
                         double& scatter_seconds, const mpi::Communicator& comm) {
  const std::optional<NpyLayout> layout =
      mode == IoMode::collective ? shared_npy_layout(path, comm) : std::optional<NpyLayout>();
  ArrayShare share;
  Array whole;
  share.shape = layout ? layout->shape : read_whole_on_root(path, whole, comm);
  comm.run([&] {
    if (comm.rank() == 0) check(share.shape);
  });
  const Shares shares = shares_for(share.shape);
  const auto rank = static_cast<std::size_t>(comm.rank());
  share.first = static_cast<std::size_t>(shares.displs[rank]);
  if (layout) {
    share.local = read_values_at_all(path, *layout, share.first, shares.count(comm.rank()), comm);
  } else {
    const StopWatch watch;
    share.local = scatter(whole.data.data(), shares, comm);
    scatter_seconds += watch.seconds();
  }
  return share;
}

void require_finite_share(std::span<const double> local, std::size_t first,
                          const std::function<Error(std::size_t index, bool nan)>& error,
                          const mpi::Communicator& comm) {
  const NpyRun run{first, local};
  require_finite_runs(std::span<const NpyRun>(&run, 1), error, comm);
}

void require_finite_runs(std::span<const NpyRun> runs, const std::function<Error(std::size_t index, bool nan)>& error,
                         const mpi::Communicator& comm) {
  // 2 i + (0 for NaN, 1 for infinite) of the first bad value: the minimum over the runs and the
  // ranks is the first bad value of the whole array and says which it is.
  constexpr std::uint64_t kNone = std::numeric_limits<std::uint64_t>::max();
  std::uint64_t mine = kNone, first_bad = kNone;
  for (const NpyRun& run : runs) {
    if (const auto i = first_nonfinite(run.values))
      mine = std::min(mine, 2 * std::uint64_t(run.first + *i) + (std::isnan(run.values[*i]) ? 0 : 1));
  }
  mpi::check_mpi(MPI_Allreduce(&mine, &first_bad, 1, MPI_UINT64_T, MPI_MIN, comm.get()), "MPI_Allreduce");
  if (first_bad == kNone) return;
  comm.run([&] {
    if (comm.rank() == 0) throw error(static_cast<std::size_t>(first_bad / 2), first_bad % 2 == 0);
  });
}

}  // namespace rpyfmm::cli
