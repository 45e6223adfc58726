// rpyfmm — the exact near field of DistributedFmmRpy (fmm_rpy_near.hpp).
#include "fmm_rpy_near.hpp"

#include <algorithm>
#include <limits>
#include <memory>

#include "alltoallv.hpp"
#include "essential_near.hpp"
#include "fmm_near_field.hpp"
#include "fmm_plan.hpp"
#include "rpyfmm/mpi/partition.hpp"
#include "stage_timer.hpp"

namespace rpyfmm::mpi::detail {
namespace {

constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();

// Collective: the radii of the serial FMM's particles (owned, then per rank its halo particles),
// moved as the positions were (to the owners, then to the ranks holding them as halo); adds the
// bytes received to `bytes`.
std::vector<double> particle_radii(const Communicator& comm, const Plan& plan, std::span<const double> local_radii,
                                   std::uint64_t& bytes) {
  const Column column{local_radii, 1};
  std::vector<double> radii = plan.partition->to_owners(std::span<const Column>(&column, 1))[0];
  const std::vector<double> halo = post_halo_charges(comm, plan, radii, 1)->wait();
  bytes += (radii.size() + halo.size()) * sizeof(double);
  radii.insert(radii.end(), halo.begin(), halo.end());
  return radii;
}

// The near field of one serial FMM with its sources renumbered as particles (owned, then halo;
// equivalent nodes left out): particle_of maps the plan's essential sources to particles.
fmm::NearField over_particles(const NearPiece& in, std::span<const std::size_t> particle_of) {
  fmm::NearField near;
  near.target_begin = in.near->target_begin;
  near.target_index = in.near->target_index;
  near.pairs = in.near->pairs;
  near.source_begin.push_back(0);
  for (std::size_t leaf = 0; leaf < in.near->num_leaves(); ++leaf) {
    for (std::size_t j : in.near->sources(leaf)) {
      const std::size_t p = particle_of[in.offset + j];
      if (p != kNone) near.source_index.push_back(p);
    }
    near.source_begin.push_back(near.source_index.size());
  }
  return near;
}

// The near field with the sources that `keep` accepts, and the pairs whose source leaf keeps one.
template <class Keep>
fmm::NearField with_sources(const fmm::NearField& near, const Keep& keep) {
  fmm::NearField out;
  out.target_begin = near.target_begin;
  out.target_index = near.target_index;
  out.source_begin.push_back(0);
  for (std::size_t leaf = 0; leaf < near.num_leaves(); ++leaf) {
    for (std::size_t p : near.sources(leaf))
      if (keep(p)) out.source_index.push_back(p);
    out.source_begin.push_back(out.source_index.size());
  }
  for (const auto& pair : near.pairs)
    if (out.source_begin[pair.second + 1] > out.source_begin[pair.second]) out.pairs.push_back(pair);
  return out;
}

// Whether the owned particles (0 .. owned - 1) among each leaf's sources are its targets: then the
// owned pairs can be evaluated once for both directions (rpy/src/fmm_near_field.hpp's symmetric
// tasks take a leaf's targets as its sources).
bool owned_sources_are_targets(const fmm::NearField& near, std::size_t owned) {
  std::vector<std::size_t> sources, targets;
  for (std::size_t leaf = 0; leaf < near.num_leaves(); ++leaf) {
    sources.clear();
    for (std::size_t p : near.sources(leaf))
      if (p < owned) sources.push_back(p);
    const std::span<const std::size_t> at = near.targets(leaf);
    targets.assign(at.begin(), at.end());
    std::sort(sources.begin(), sources.end());
    std::sort(targets.begin(), targets.end());
    if (sources != targets) return false;
  }
  return true;
}

}  // namespace

RpyNearField::RpyNearField(const Communicator& comm, const DistributedLaplaceFmm& laplace,
                           std::span<const double> local_radii, bool equal, double radius)
    : plan_(laplace.plan()), equal_(equal) {
  const Plan& plan = *plan_;
  owned_ = plan.owned_x.size() / 3;
  essential_ = plan.sources;
  std::vector<double> radii;  // of the particles, in essential order
  if (!equal)
    detail::timed(setup_.seconds, [&] { radii = particle_radii(comm, plan, local_radii, setup_.bytes_received); });
  if (essential_ == 0) return;  // no serial FMM on this rank: no owned particle
  // Particles: every essential source that is not an equivalent node, in essential order.
  const std::vector<std::uint8_t> node = node_sources(plan);
  std::vector<std::size_t> particle_of(essential_, kNone);
  for (std::size_t e = 0; e < essential_; ++e) {
    if (node[e] != 0) continue;
    particle_of[e] = essential_of_.size();
    essential_of_.push_back(e);
    x_.insert(x_.end(), plan.essential_x.begin() + static_cast<std::ptrdiff_t>(3 * e),
              plan.essential_x.begin() + static_cast<std::ptrdiff_t>(3 * e + 3));
  }
  particles_ = essential_of_.size();
  a_ = equal ? std::vector<double>(particles_, radius) : std::move(radii);
  for (const NearPiece& in : near_pieces(plan)) {
    fmm::NearField near = over_particles(in, particle_of);
    if (in.same_points || !owned_sources_are_targets(near, owned_)) {
      add_piece(std::move(near), in.same_points);
      continue;
    }
    // Owned and halo sources: the owned pairs once for both directions, as at the serial FMM's own
    // sources, then the halo particles on the owned targets, one-sided.
    fmm::NearField halo = with_sources(near, [&](std::size_t p) { return p >= owned_; });
    add_piece(with_sources(near, [&](std::size_t p) { return p < owned_; }), true);
    if (!halo.pairs.empty()) add_piece(std::move(halo), false);
  }
}

void RpyNearField::add_piece(fmm::NearField near, bool same_points) {
  Piece& piece = pieces_.emplace_back();
  piece.near = std::move(near);
  piece.schedule = rpy::detail::near_schedule_for(piece.near, same_points);
  piece.one_sided = rpy::detail::near_schedule_for(piece.near, false);
}

std::vector<double> RpyNearField::gather_loads(const std::vector<double>& essential,
                                               std::span<const std::size_t> first) const {
  std::vector<double> loads(3 * particles_ * first.size());
  for (std::size_t b = 0; b < first.size(); ++b)
    for (std::size_t p = 0; p < particles_; ++p)
      for (std::size_t c = 0; c < 3; ++c)
        loads[3 * particles_ * b + 3 * p + c] = essential[(first[b] + c) * essential_ + essential_of_[p]];
  return loads;
}

void RpyNearField::add_back(const std::vector<double>& owned, std::size_t blocks, std::span<double* const> to) const {
  const SfcPartition& partition = *plan_->partition;
  std::vector<Column> columns;
  for (std::size_t b = 0; b < blocks; ++b)
    columns.push_back({std::span<const double>(owned.data() + 3 * particles_ * b, 3 * owned_), 3});
  std::vector<std::vector<double>> back;
  back_.seconds = 0.0;
  detail::timed(back_.seconds, [&] { back = partition.to_origin(columns); });
  const std::size_t n = partition.input_size();
  back_.bytes_received = blocks * 3 * n * sizeof(double);
  for (std::size_t b = 0; b < blocks; ++b)
    for (std::size_t i = 0; i < 3 * n; ++i) to[b][i] += back[b][i];
}

// The translational near sums of one right-hand side (3 particles_ forces) into velocities of the
// same layout.
void RpyNearField::translational_sums(const double* forces, double inv_eta, double* velocities) const {
  for (std::size_t i = 0; i < pieces_.size(); ++i) {
    // The self terms once per target: every owned target lies in a leaf of the first piece.
    const rpy::detail::NearPoints points{pieces_[i].near, pieces_[i].schedule, x_, a_, particles_, equal_, i == 0};
    rpy::detail::add_near_velocities(points, forces, velocities, 1, inv_eta);
  }
}

void RpyNearField::add_velocities(const std::vector<double>& essential, std::size_t per_rhs, std::size_t nrhs,
                                  double inv_eta, std::span<double> local_u) const {
  std::vector<double> velocities(3 * particles_ * nrhs, 0.0);
  sums_seconds_ = 0.0;
  detail::timed(sums_seconds_, [&] {
    std::vector<std::size_t> first(nrhs);
    for (std::size_t k = 0; k < nrhs; ++k) first[k] = k * per_rhs;
    const std::vector<double> forces = gather_loads(essential, first);
    // One right-hand side at a time, each as in a product of it alone (the kernels for several
    // right-hand sides order their operations otherwise), so that each is apply's bit for bit.
    for (std::size_t k = 0; k < nrhs; ++k)
      translational_sums(forces.data() + 3 * particles_ * k, inv_eta, velocities.data() + 3 * particles_ * k);
  });
  const std::size_t n = plan_->partition->input_size();
  std::vector<double*> to(nrhs);
  for (std::size_t k = 0; k < nrhs; ++k) to[k] = local_u.data() + 3 * n * k;
  add_back(velocities, nrhs, to);
}

void RpyNearField::add_grand(const std::vector<double>& essential, std::size_t per_rhs, double inv_eta,
                             std::span<double> local_u, std::span<double> local_ut, std::span<double> local_w) const {
  std::vector<double> sums(9 * particles_, 0.0);  // U from F (times 1 / eta), U from T, W
  sums_seconds_ = 0.0;
  detail::timed(sums_seconds_, [&] {
    const std::size_t first[] = {0, per_rhs};
    const std::vector<double> loads = gather_loads(essential, first);  // F, then T
    translational_sums(loads.data(), inv_eta, sums.data());
    for (std::size_t i = 0; i < pieces_.size(); ++i) {
      const rpy::detail::NearPoints points{pieces_[i].near, pieces_[i].one_sided, x_, a_, particles_, equal_, i == 0};
      rpy::detail::add_rotation_near_field(points, loads.data(), sums.data() + 3 * particles_,
                                           sums.data() + 6 * particles_);
    }
  });
  double* const to[] = {local_u.data(), local_ut.data(), local_w.data()};
  add_back(sums, 3, to);
}

}  // namespace rpyfmm::mpi::detail
