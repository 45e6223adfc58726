// rpyfmm — the particle checks and whole-set summaries of the distributed RPY operators
// (particle_set.hpp).
#include "particle_set.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::mpi::detail {
namespace {

// A rank's summary: lo[3], hi[3], the global indices of the particles on the box faces ilo[3],
// ihi[3] (exact as doubles), a_min, a_max, count.
constexpr int kSummary = 15;

std::array<double, kSummary> local_summary(std::span<const double> x, std::span<const double> a, std::size_t offset) {
  std::array<double, kSummary> s{};
  s[14] = static_cast<double>(a.size());
  if (a.empty()) return s;
  const rpy::detail::BoundingBox box = rpy::detail::bounding_box(x);
  for (int c = 0; c < 3; ++c) {
    s[c] = box.lo[c];
    s[3 + c] = box.hi[c];
    s[6 + c] = static_cast<double>(offset + box.ilo[c]);
    s[9 + c] = static_cast<double>(offset + box.ihi[c]);
  }
  const auto [a_min, a_max] = std::minmax_element(a.begin(), a.end());
  s[12] = *a_min;
  s[13] = *a_max;
  return s;
}

// A face moves only to a strictly lower (higher) coordinate, so the first particle on it names it.
WholeSet merge_summaries(const std::vector<double>& all, std::size_t ranks) {
  WholeSet set;
  bool first = true;
  for (std::size_t r = 0; r < ranks; ++r) {
    const double* s = all.data() + kSummary * r;
    if (s[14] == 0.0) continue;
    for (std::size_t c = 0; c < 3; ++c) {
      if (first || s[c] < set.box.lo[c]) set.box.lo[c] = s[c], set.box.ilo[c] = static_cast<std::size_t>(s[6 + c]);
      if (first || s[3 + c] > set.box.hi[c]) {
        set.box.hi[c] = s[3 + c], set.box.ihi[c] = static_cast<std::size_t>(s[9 + c]);
      }
    }
    set.radii.a_min = first ? s[12] : std::min(set.radii.a_min, s[12]);
    set.radii.a_max = first ? s[13] : std::max(set.radii.a_max, s[13]);
    first = false;
  }
  return set;
}

}  // namespace

double agreed_viscosity(const Communicator& comm, double viscosity, const char* where) {
  comm.run([&] { require_positive(viscosity, where, "viscosity"); });
  std::array<double, 2> local{viscosity, -viscosity}, global{};
  check_mpi(MPI_Allreduce(local.data(), global.data(), 2, MPI_DOUBLE, MPI_MIN, comm.get()), "MPI_Allreduce");
  require(global[0] == -global[1], ErrorCode::invalid_argument, where,
          "the ranks pass different viscosities (from " + format_number(global[0]) + " to " +
              format_number(-global[1]) + "); every rank must pass the same one");
  return viscosity;
}

void agree_on_nrhs(const Communicator& comm, std::size_t nrhs, const char* where) {
  comm.run([&] { require(nrhs > 0, ErrorCode::invalid_argument, where, "number of right-hand sides must be > 0"); });
  require(same_on_every_rank(comm, {static_cast<double>(nrhs)}), ErrorCode::invalid_argument, where,
          "the ranks pass different numbers of right-hand sides (nrhs); every rank must pass the same");
}

void check_local_particles(std::span<const double> positions, std::span<const double> radii, const char* where) {
  require(positions.size() % 3 == 0, ErrorCode::invalid_input, where,
          "local positions have " + std::to_string(positions.size()) + " entries, not a multiple of 3");
  require_size(radii, positions.size() / 3, where, "local radii");
  require_finite(positions, where, "local positions", 3);
  for (std::size_t i = 0; i < radii.size(); ++i) {
    if (!(std::isfinite(radii[i]) && radii[i] > 0.0)) {
      fail(ErrorCode::invalid_argument, where,
           "radius of local particle " + std::to_string(i) + " must be finite and > 0, got " + format_number(radii[i]));
    }
  }
}

std::vector<double> common_radii(const Communicator& comm, std::span<const double> positions, double radius,
                                 const char* where) {
  comm.run([&] { require_positive(radius, where, "radius"); });
  return std::vector<double>(positions.size() / 3, radius);
}

std::vector<std::size_t> gather_counts(const Communicator& comm, std::size_t local_n) {
  const auto mine = static_cast<std::uint64_t>(local_n);
  std::vector<std::uint64_t> all(static_cast<std::size_t>(comm.size()));
  check_mpi(MPI_Allgather(&mine, 1, MPI_UINT64_T, all.data(), 1, MPI_UINT64_T, comm.get()), "MPI_Allgather");
  return {all.begin(), all.end()};
}

WholeSet gather_whole_set(const Communicator& comm, std::span<const double> x, std::span<const double> a,
                          std::size_t offset) {
  const auto ranks = static_cast<std::size_t>(comm.size());
  const std::array<double, kSummary> summary = local_summary(x, a, offset);
  std::vector<double> summaries(kSummary * ranks);
  check_mpi(MPI_Allgather(summary.data(), kSummary, MPI_DOUBLE, summaries.data(), kSummary, MPI_DOUBLE, comm.get()),
            "MPI_Allgather");
  WholeSet set = merge_summaries(summaries, ranks);
  set.radii.first = offset;
  return set;
}

}  // namespace rpyfmm::mpi::detail
