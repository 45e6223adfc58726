// rpyfmm — Brownian dynamics across MPI ranks (rpyfmm/mpi/brownian_dynamics.hpp;
// docs/mpi.md, "Brownian dynamics across ranks").
#include "rpyfmm/mpi/brownian_dynamics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <sstream>
#include <string>
#include <utility>

#include "alltoallv.hpp"
#include "bd_gather.hpp"
#include "bd_halo.hpp"
#include "bd_hydrodynamics.hpp"
#include "device/engine_tables.hpp"
#include "device/euler_maruyama.hpp"
#include "device/rebuild_test.hpp"
#include "rpyfmm/bd/langevin.hpp"
#include "rpyfmm/bd/output.hpp"
#include "rpyfmm/bd/quaternion.hpp"
#include "rpyfmm/bd/rotation_sampling.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/partition.hpp"
#include "rpyfmm/rpy/free_draining.hpp"
#include "rpyfmm/rpy/random.hpp"

namespace rpyfmm::mpi {
namespace {

constexpr const char* kWhere = "DistributedBd";
constexpr std::uint64_t kNoParticle = std::numeric_limits<std::uint64_t>::max();

// The imbalance threshold and the curve.
void require_supported(const DistributedBdOptions& o) {
  require(o.repartition_imbalance >= 1.0, ErrorCode::invalid_argument, kWhere,
          "repartition_imbalance must be >= 1 (infinity: never), got " + std::to_string(o.repartition_imbalance));
  require(o.curve == SfcCurve::morton || o.curve == SfcCurve::hilbert, ErrorCode::invalid_argument, kWhere,
          "curve must be SfcCurve::morton or SfcCurve::hilbert, got " + std::to_string(static_cast<int>(o.curve)));
}

// Whether the particles of type t are inertial (IntegratorOptions::inertia, as bd::LangevinGroup
// reads it: types past the end are Brownian).
bool inertial_type(const bd::IntegratorOptions& o, std::uint32_t t) {
  return t < o.inertia.size() && o.inertia[t].has_value();
}

// The owned inertial particles: their masses and frictions, global indices (the noise keys) and
// places among the owned particles, in increasing global index.
struct InertialSubset {
  std::vector<bd::LangevinParticle> particles;
  std::vector<std::uint64_t> index;
  std::vector<std::size_t> local;
};

InertialSubset inertial_subset(const bd::IntegratorOptions& o, std::span<const std::uint32_t> types,
                               std::span<const std::uint64_t> ids) {
  InertialSubset s;
  for (std::size_t i = 0; i < types.size(); ++i) {
    if (!inertial_type(o, types[i])) continue;
    s.particles.push_back(*o.inertia[types[i]]);
    s.index.push_back(ids[i]);
    s.local.push_back(i);
  }
  return s;
}

// The serial engine's conditions on inertial particles (bd::Integrator::check_inertia); the
// options are the same on every rank, so every rank throws alike.
void check_inertia(const DistributedBdOptions& o) {
  require(o.method == rpy::MobilityMethod::none, ErrorCode::invalid_argument, kWhere,
          "inertial (Langevin) particles need the free-draining mobility \"none\": hydrodynamic interactions "
          "with inertia are not supported");
  require(!o.integrator.rotation, ErrorCode::invalid_argument, kWhere,
          "inertial (Langevin) particles do not support rotation yet");
  require(!o.integrator.keep_split_displacements, ErrorCode::invalid_argument, kWhere,
          "split displacements (M F dt and the Brownian part) do not apply to inertial (Langevin) particles");
}

// This rank's velocities and inertial types checked as bd::LangevinGroup checks them (not
// collective): masses and frictions finite and > 0; velocities empty or 3 per particle, finite,
// and 0 for Brownian particles.
void check_inertial_share(const BdShare& s, const bd::IntegratorOptions& o) {
  for (const std::uint32_t t : s.types)
    require(!inertial_type(o, t) || (std::isfinite(o.inertia[t]->mass) && o.inertia[t]->mass > 0.0 &&
                                     std::isfinite(o.inertia[t]->friction) && o.inertia[t]->friction > 0.0),
            ErrorCode::invalid_argument, kWhere, "inertia: mass and friction must be finite and > 0");
  if (s.velocities.empty()) return;
  const std::size_t n = s.types.size();
  require(s.velocities.size() == 3 * n, ErrorCode::invalid_input, kWhere,
          "velocities has " + std::to_string(s.velocities.size()) + " entries, expected 3n = " + std::to_string(3 * n) +
              " (this rank's share)");
  require_finite(s.velocities, kWhere, "velocities", 3);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t c = 0; c < 3 && !inertial_type(o, s.types[i]); ++c)
      require(s.velocities[3 * i + c] == 0.0, ErrorCode::invalid_input, kWhere,
              "particle " + std::to_string(i) + " (of this rank's share) is Brownian but has a non-zero velocity");
}

// Collective: throws on every rank unless the ranks with particles all give `what` or none does
// (ranks without particles count as both).
void require_all_or_none(const Communicator& comm, bool has_particles, bool given, const std::string& what) {
  const double flags[2] = {!has_particles || given ? 1.0 : 0.0, !has_particles || !given ? 1.0 : 0.0};
  double all[2] = {0.0, 0.0};
  check_mpi(MPI_Allreduce(flags, all, 2, MPI_DOUBLE, MPI_MIN, comm.get()), "MPI_Allreduce");
  require(all[0] == 1.0 || all[1] == 1.0, ErrorCode::invalid_input, kWhere,
          "some ranks gave " + what + " and others did not (give them on every rank with particles, or on none)");
}

// The step's constants as the device stages take them (the serial engine's arithmetic,
// bd/src/device/euler_maruyama.hpp); checks dt, kT, max_displacement and the viscosity.
bd::device::EngineTables motion_tables(const DistributedBdOptions& o, const bd::ForceField& forces) {
  bd::device::EngineOptions e;
  e.dt = o.integrator.dt;
  e.kT = o.integrator.kT;
  e.seed = o.integrator.seed;
  e.max_displacement = o.integrator.max_displacement;
  e.viscosity = o.viscosity;
  return bd::device::make_motion_tables(forces, e);
}

std::vector<double> option_signature(const DistributedBdOptions& o, const rpy::Geometry& g,
                                     const bd::ForceField& forces) {
  const bd::IntegratorOptions& i = o.integrator;
  return {i.dt,
          i.kT,
          static_cast<double>(i.seed & 0xFFFFFFFFu),
          static_cast<double>(i.seed >> 32),
          i.max_displacement,
          o.viscosity,
          o.neighbours.skin,
          static_cast<double>(o.neighbours.fixed_interval),
          o.repartition_imbalance,
          static_cast<double>(o.repartition_cost),
          g.is_periodic() ? 1.0 : 0.0,
          g.box()[0],
          g.box()[1],
          g.box()[2],
          static_cast<double>(forces.types().size()),
          static_cast<double>(forces.bonds().size()),
          forces.max_cutoff(),
          forces.trap_stiffness(),
          static_cast<double>(o.method),
          o.fmm.tolerance,
          static_cast<double>(o.fmm.leaf_capacity),
          static_cast<double>(i.sqrt.method),
          i.sqrt.tolerance,
          o.pse.tolerance,
          o.pse.xi,
          o.pse.r_cut,
          static_cast<double>(o.pse.grid[0]),
          static_cast<double>(o.pse.grid[1]),
          static_cast<double>(o.pse.grid[2]),
          static_cast<double>(o.pse.support),
          o.pse.window_eta,
          o.pse.lanczos_tolerance,
          i.rotation ? 1.0 : 0.0,
          i.keep_split_displacements ? 1.0 : 0.0,
          static_cast<double>(forces.callbacks().size()),
          i.sac.enabled ? 1.0 : 0.0,
          i.sac.adsorption_factor,
          static_cast<double>(o.curve)};
}

// option_signature with the inertial types' masses and frictions (0 for Brownian types).
std::vector<double> full_signature(const DistributedBdOptions& o, const rpy::Geometry& g,
                                   const bd::ForceField& forces) {
  std::vector<double> s = option_signature(o, g, forces);
  s.push_back(static_cast<double>(o.integrator.inertia.size()));
  for (const auto& t : o.integrator.inertia) s.insert(s.end(), {t ? t->mass : 0.0, t ? t->friction : 0.0});
  return s;
}

// Collective: the exclusive prefix sum and the total of this rank's count.
std::pair<std::uint64_t, std::uint64_t> offset_and_total(const Communicator& comm, std::uint64_t count) {
  std::uint64_t offset = 0, total = 0;
  check_mpi(MPI_Exscan(&count, &offset, 1, MPI_UINT64_T, MPI_SUM, comm.get()), "MPI_Exscan");
  if (comm.rank() == 0) offset = 0;  // MPI_Exscan leaves rank 0's result undefined
  check_mpi(MPI_Allreduce(&count, &total, 1, MPI_UINT64_T, MPI_SUM, comm.get()), "MPI_Allreduce");
  return {offset, total};
}

// This rank's checks of its share (not collective).
void check_share(const BdShare& s, const bd::ForceField& forces) {
  const std::size_t n = s.types.size();
  require(s.positions.size() == 3 * n, ErrorCode::invalid_input, kWhere,
          "positions must hold 3 values per particle: " + std::to_string(s.positions.size()) + " for " +
              std::to_string(n) + " types");
  require(
      s.ids.empty() || s.ids.size() == n, ErrorCode::invalid_input, kWhere,
      "ids must be empty or hold one per particle, got " + std::to_string(s.ids.size()) + " for " + std::to_string(n));
  require(s.reference_positions.empty() || s.reference_positions.size() == 3 * n, ErrorCode::invalid_input, kWhere,
          "reference_positions must be empty or hold 3 values per particle");
  for (std::size_t k = 0; k < s.positions.size(); ++k) {
    require(std::isfinite(s.positions[k]), ErrorCode::invalid_input, kWhere,
            "position of particle " + std::to_string(k / 3) + " (of this rank's share) is not finite");
  }
  for (const double r : s.reference_positions)
    require(std::isfinite(r), ErrorCode::invalid_input, kWhere, "a reference position is not finite");
  forces.with_bonds({}).check(s.types);  // the types; the bonds index the whole system (BondIndex)
}

// This rank's orientations, those at step 0 and summed rotation vectors checked and completed
// (not collective): with rotation, quaternions as bd::Integrator takes them (quaternion::checked:
// finite, not zero, normalized unless unit to 1e-14), empty ones the identity, the orientations and
// zeros; without rotation all must be empty.
void complete_rotation_state(BdShare& s, bool rotation) {
  const std::size_t n = s.types.size();
  if (!rotation) {
    require(s.orientations.empty() && s.reference_orientations.empty() && s.rotation_vectors.empty(),
            ErrorCode::invalid_argument, kWhere, "orientations or rotation vectors given but rotation is off");
    return;
  }
  constexpr const char* kObject = "particle (index in this rank's share)";
  s.orientations = bd::quaternion::checked(std::move(s.orientations), n, kWhere, kObject);
  s.reference_orientations = s.reference_orientations.empty()
                                 ? s.orientations
                                 : bd::quaternion::checked(std::move(s.reference_orientations), n, kWhere, kObject);
  if (s.rotation_vectors.empty()) s.rotation_vectors.assign(3 * n, 0.0);
  require(s.rotation_vectors.size() == 3 * n, ErrorCode::invalid_input, kWhere,
          "rotation_vectors must be empty or hold 3 values per particle");
  require_finite(s.rotation_vectors, kWhere, "rotation_vectors", 3);
}

// Collective: throws on every rank unless the ids of all ranks are 0 ... total - 1, each once. Each
// id goes to the rank of its block of the range, which checks its block.
void check_permutation(const Communicator& comm, std::span<const std::uint64_t> ids, std::uint64_t total) {
  const auto p = static_cast<std::uint64_t>(comm.size());
  const auto block_of = [&](std::uint64_t id) { return static_cast<std::size_t>((id * p) / total); };
  std::optional<Error> problem;
  std::vector<std::vector<double>> send(comm.size());
  for (const std::uint64_t id : ids) {
    if (id >= total) {
      if (!problem)
        problem = Error(ErrorCode::invalid_input, std::string(kWhere) + ": particle id " + std::to_string(id) +
                                                      " is not below the number of particles " + std::to_string(total));
      continue;
    }
    send[block_of(id)].push_back(static_cast<double>(id));
  }
  comm.agree(problem);
  std::vector<double> mine = detail::alltoallv(comm, send, kWhere, "the particle ids");
  std::sort(mine.begin(), mine.end());
  const std::uint64_t first = (static_cast<std::uint64_t>(comm.rank()) * total + p - 1) / p;
  for (std::size_t k = 0; k < mine.size() && !problem; ++k) {
    if (static_cast<std::uint64_t>(mine[k]) != first + k)
      problem = Error(ErrorCode::invalid_input, std::string(kWhere) + ": particle id " +
                                                    std::to_string(static_cast<std::uint64_t>(mine[k])) +
                                                    " is given twice (ids must number the particles 0 ... N - 1)");
  }
  comm.agree(problem);
}

// With rotation, the values of a particle that travel with it besides its position: orientation,
// orientation at step 0 and summed rotation vector (4 + 4 + 3).
constexpr std::size_t kRotationValues = 11;

// Appends particle i's rotation values to `packed`.
void pack_rotation(std::vector<double>& packed, std::span<const double> q, std::span<const double> reference,
                   std::span<const double> sum, std::size_t i) {
  packed.insert(packed.end(), &q[4 * i], &q[4 * i + 4]);
  packed.insert(packed.end(), &reference[4 * i], &reference[4 * i + 4]);
  packed.insert(packed.end(), &sum[3 * i], &sum[3 * i + 3]);
}

// Particle i's rotation values from v (pack_rotation's layout) into the arrays.
void unpack_rotation(const double* v, std::size_t i, std::vector<double>& q, std::vector<double>& reference,
                     std::vector<double>& sum) {
  std::copy(v, v + 4, &q[4 * i]);
  std::copy(v + 4, v + 8, &reference[4 * i]);
  std::copy(v + 8, v + 11, &sum[3 * i]);
}

// The owned arrays sorted by global index (their order everywhere in the engine).
template <class T>
std::vector<T> permuted(const std::vector<T>& v, std::span<const std::size_t> order, std::size_t per) {
  std::vector<T> out(v.size());
  for (std::size_t i = 0; i < order.size(); ++i)
    for (std::size_t c = 0; c < per; ++c) out[per * i + c] = v[per * order[i] + c];
  return out;
}

}  // namespace

DistributedBd::DistributedBd(MPI_Comm comm, bd::ForceField forces, rpy::Geometry geometry, DistributedBdOptions options,
                             BdShare share, std::uint64_t first_step)
    : comm_(comm),
      forces_(forces.without_callbacks()),  // compute_rows takes a part of the system; callbacks_ the whole
      callbacks_(forces.callbacks().begin(), forces.callbacks().end()),
      geometry_(geometry),
      options_(std::move(options)),
      step_(first_step) {
  comm_.run([&] {
    require_supported(options_);
    (void)motion_tables(options_, forces_);
    (void)bd::NeighbourList(geometry_, forces_.max_cutoff(), options_.neighbours);  // its checks of the skin and box
    check_share(share, forces_);
    complete_rotation_state(share, options_.integrator.rotation);
    check_inertial_share(share, options_.integrator);
  });
  require(same_on_every_rank(comm_, full_signature(options_, geometry_, forces)), ErrorCode::invalid_argument, kWhere,
          "the ranks passed different options, geometries or force fields");
  require_all_or_none(comm_, !share.types.empty(), !share.ids.empty(), "particle ids");
  require_all_or_none(comm_, !share.types.empty(), !share.velocities.empty(), "velocities");
  const int mine_inertial = std::any_of(share.types.begin(), share.types.end(),
                                        [&](std::uint32_t t) { return inertial_type(options_.integrator, t); })
                                ? 1
                                : 0;
  int any_inertial = 0;
  check_mpi(MPI_Allreduce(&mine_inertial, &any_inertial, 1, MPI_INT, MPI_MAX, comm_.get()), "MPI_Allreduce");
  inertial_ = any_inertial != 0;
  if (inertial_) check_inertia(options_);
  if (options_.integrator.sac.enabled) check_sac(share.types);
  comm_.run([&] {
    require(inertial_ || share.velocities.empty(), ErrorCode::invalid_argument, kWhere,
            "velocities given but no particle is inertial");
  });
  const auto [offset, total] = offset_and_total(comm_, share.types.size());
  require(total > 0, ErrorCode::invalid_input, kWhere, "no particles on any rank (N = 0)");
  require(total < (std::uint64_t{1} << 53), ErrorCode::not_supported, kWhere,
          "more than 2^53 particles (ids travel as doubles)");
  global_n_ = total;
  bonds_ = std::make_unique<detail::BondIndex>(forces_.bonds(), total);  // checks the bonds against N
  if (share.ids.empty()) {
    share.ids.resize(share.types.size());
    std::iota(share.ids.begin(), share.ids.end(), offset);
  }
  check_permutation(comm_, share.ids, total);
  if (share.reference_positions.empty()) share.reference_positions = share.positions;
  std::vector<std::size_t> order(share.ids.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return share.ids[a] < share.ids[b]; });
  x_ = permuted(share.positions, order, 3);
  reference_ = permuted(share.reference_positions, order, 3);
  types_ = permuted(share.types, order, 1);
  ids_ = permuted(share.ids, order, 1);
  if (options_.integrator.rotation) {
    q_ = permuted(share.orientations, order, 4);
    reference_q_ = permuted(share.reference_orientations, order, 4);
    rotation_sum_ = permuted(share.rotation_vectors, order, 3);
    torque_.assign(3 * ids_.size(), 0.0);
    phi_.assign(3 * ids_.size(), 0.0);
  }
  if (inertial_) start_velocities(share.velocities, order);
  hydrodynamics_ = Hydrodynamics::make(comm_.get(), options_, geometry_);
  for (const char* part : {"rebuild", "halo", "forces", "update"}) stats_.seconds[part] = 0.0;
  if (sac_) {  // the complexes at the starting positions, as the serial engine finds them
    prepare_part();
    part_ready_ = true;
  }
}

DistributedBd::~DistributedBd() = default;
DistributedBd::DistributedBd(DistributedBd&&) noexcept = default;
DistributedBd& DistributedBd::operator=(DistributedBd&&) noexcept = default;

void DistributedBd::step() {
  // 1. Lists, halo and partition when the rebuild test asked for them (Tran et al. (2015),
  //    Algorithm 1), else the halo's new positions; with the SAC scheme the part was prepared at
  //    the end of the last step (the complexes at the current positions).
  if (!part_ready_) prepare_part();
  part_ready_ = false;
  // 2. Forces on the owned particles, from the part in the serial engine's order.
  StopWatch watch;
  compute_forces();
  stats_.seconds["forces"] += watch.seconds();
  // 3. dx = mu F dt + sqrt(2 kT dt mu) z, the blow-up guard, x += dx and the next rebuild test.
  watch.restart();
  advance();
  stats_.seconds["update"] += watch.seconds();
  // 4. With the SAC scheme, the complexes of the new positions (those of the next step, which
  //    bd::Integrator also finds at the end of its step).
  if (sac_) {
    prepare_part();
    part_ready_ = true;
  }
}

void DistributedBd::prepare_part() {
  StopWatch watch;
  if (rebuild_due_) {
    rebuild();
    stats_.seconds["rebuild"] += watch.seconds();
  } else {
    halo_->refresh(comm_, x_);
    stats_.seconds["halo"] += watch.seconds();
  }
  if (sac_) update_complexes();
}

void DistributedBd::run(std::uint64_t count) {
  for (std::uint64_t k = 0; k < count; ++k) step();
}

void DistributedBd::rebuild() {
  // The ranks' costs: their particles and their list entries (the forces' pair work).
  // The ranks' costs: the model's (their particles and list entries, the forces' pair work) or the
  // measured seconds of their own work, spread over their particles as the model's weights.
  const std::vector<double> rows = halo_ ? halo_->row_lengths() : std::vector<double>(ids_.size(), 0.0);
  std::vector<double> weights(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) weights[i] = 1.0 + rows[i];
  const double model_cost = std::accumulate(weights.begin(), weights.end(), 0.0);
  const bool measured = halo_ && options_.repartition_cost == DistributedBdOptions::Cost::measured_time;
  const double cost = measured ? work_seconds_ : model_cost;
  if (measured && model_cost > 0.0)
    for (double& w : weights) w *= work_seconds_ / model_cost;
  double max_cost = 0.0, total_cost = 0.0;
  check_mpi(MPI_Allreduce(&cost, &max_cost, 1, MPI_DOUBLE, MPI_MAX, comm_.get()), "MPI_Allreduce");
  check_mpi(MPI_Allreduce(&cost, &total_cost, 1, MPI_DOUBLE, MPI_SUM, comm_.get()), "MPI_Allreduce");
  const double mean = total_cost / comm_.size();
  stats_.imbalance = mean > 0.0 ? max_cost / mean : 1.0;
  if (!halo_ || (comm_.size() > 1 && stats_.imbalance > options_.repartition_imbalance)) repartition(weights);
  work_seconds_ = 0.0;
  halo_ = std::make_unique<Halo>(
      Halo::build(comm_, forces_, *bonds_, geometry_, options_.neighbours, x_, types_, ids_, global_n_, sac_reach_));
  list_reference_ = x_;
  rebuild_due_ = false;
  steps_since_rebuild_ = 0;
  ++stats_.rebuilds;
  stats_.halo_size = halo_->halo_rows.size();
}

void DistributedBd::repartition(std::span<const double> weights) {
  // Keys from the wrapped positions in a periodic box (the curve runs through the box once); the
  // unwrapped positions move as a column.
  const std::size_t n = ids_.size();
  std::vector<double> keyed(3 * n), id(n), type(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::array<double, 3> w = detail::wrapped(&x_[3 * i], geometry_);
    for (int c = 0; c < 3; ++c) keyed[3 * i + c] = w[c];
    id[i] = static_cast<double>(ids_[i]);
    type[i] = static_cast<double>(types_[i]);
  }
  const SfcPartition partition(comm_.get(), keyed, weights, options_.curve);
  // With rotation the orientations, those at step 0 and the summed rotation vectors travel too.
  std::vector<Column> columns = {{x_, 3}, {reference_, 3}, {id, 1}, {type, 1}};
  if (options_.integrator.rotation) columns.insert(columns.end(), {{q_, 4}, {reference_q_, 4}, {rotation_sum_, 3}});
  if (inertial_) columns.push_back({v_, 3});  // the half-step velocities travel too
  // With the SAC scheme the rebuild follows a step (step 4): the forces of that step travel too
  // (0 before the first).
  if (sac_) {
    f_.resize(3 * n, 0.0);
    columns.push_back({f_, 3});
  }
  std::vector<std::vector<double>> moved = partition.to_owners(columns);
  const std::size_t m = partition.owned_size();
  std::vector<std::size_t> order(m);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return moved[2][a] < moved[2][b]; });
  x_ = permuted(moved[0], order, 3);
  reference_ = permuted(moved[1], order, 3);
  ids_.resize(m);
  types_.resize(m);
  for (std::size_t i = 0; i < m; ++i) {
    ids_[i] = static_cast<std::uint64_t>(moved[2][order[i]]);
    types_[i] = static_cast<std::uint32_t>(moved[3][order[i]]);
  }
  if (options_.integrator.rotation) {
    q_ = permuted(moved[4], order, 4);
    reference_q_ = permuted(moved[5], order, 4);
    rotation_sum_ = permuted(moved[6], order, 3);
    torque_.assign(3 * m, 0.0);  // as the forces below
    phi_.assign(3 * m, 0.0);
  }
  if (inertial_) v_ = permuted(moved[4], order, 3);
  // Without the SAC scheme the forces of the last step belong to the particles held before.
  f_ = sac_ ? permuted(moved[5], order, 3) : std::vector<double>(3 * m, 0.0);
  if (options_.integrator.keep_split_displacements) {  // so do its split displacements
    dx_det_.assign(3 * m, 0.0);
    dx_brown_.assign(3 * m, 0.0);
  }
  ++stats_.repartitions;
}

void DistributedBd::compute_forces() {
  const std::size_t n = ids_.size();
  f_.assign(3 * n, 0.0);
  particle_energy_.assign(n, 0.0);
  comm_.run([&] {
    const StopWatch work;  // this rank's own work, without the agreement's wait for the others
    const bd::ForceField& part = halo_->part_forces ? *halo_->part_forces : forces_;  // bonds as part rows
    // With the SAC scheme: f_ from outside each particle's complex, f_within_ from inside it.
    if (sac_) f_within_.assign(3 * n, 0.0);
    part.compute_rows(halo_->x, halo_->types, halo_->list, step_, halo_->owned_rows, halo_->ids, f_, particle_energy_,
                      groups_, f_within_);
    work_seconds_ += work.seconds();
  });
  if (!callbacks_.empty()) add_callback_forces();
  if (sac_) complex_forces();
  double mine = 0.0;
  for (const double e : particle_energy_) mine += e;
  // The torques depend on each particle's own type and orientation alone (bd::TorqueField).
  if (options_.integrator.rotation) mine += forces_.torque_field().compute(q_, types_, torque_);
  check_mpi(MPI_Allreduce(&mine, &energy_, 1, MPI_DOUBLE, MPI_SUM, comm_.get()), "MPI_Allreduce");
}

void DistributedBd::add_callback_forces() {
  // bd::ForceField::compute calls the callbacks last, on the whole system's positions and the
  // forces of the other terms: the same arrays, gathered in global index order (id, x, f: 7
  // doubles per particle, one MPI_Allgatherv), so each callback does on every rank what it does
  // in the serial engine, and the owned rows of its result are the serial forces bit for bit.
  std::vector<double> packed(6 * ids_.size());
  for (std::size_t i = 0; i < ids_.size(); ++i) {
    std::copy(&x_[3 * i], &x_[3 * i + 3], &packed[6 * i]);
    std::copy(&f_[3 * i], &f_[3 * i + 3], &packed[6 * i + 3]);
  }
  const std::vector<double> all =
      detail::gather_by_index(comm_, ids_, packed, global_n_, 6, detail::kEveryRank, kWhere);
  std::vector<double> x(3 * global_n_), f(3 * global_n_);
  for (std::size_t k = 0; k < global_n_; ++k) {
    std::copy(&all[6 * k], &all[6 * k + 3], &x[3 * k]);
    std::copy(&all[6 * k + 3], &all[6 * k + 6], &f[3 * k]);
  }
  comm_.run([&] {  // a callback that throws on one rank fails every rank
    for (const bd::ForceCallback& callback : callbacks_) callback(x, step_, f);
  });
  for (std::size_t i = 0; i < ids_.size(); ++i) std::copy(&f[3 * ids_[i]], &f[3 * ids_[i] + 3], &f_[3 * i]);
}

void DistributedBd::advance() {
  const std::size_t n = ids_.size();
  // z_i keyed by the global index, drawn as the serial engine draws it (rpy::fill_normal); the pse
  // operator draws its own without rotation (bd::Integrator fuses drift and noise then only).
  // With split displacements the drift and the noise are separate products (as bd::Integrator's).
  const bool rotation = options_.integrator.rotation, split = options_.integrator.keep_split_displacements;
  const bool fused = hydrodynamics_ && hydrodynamics_->fused() && !rotation && !split;
  const bool drawn = options_.integrator.kT > 0.0 && !fused;
  z_.assign(drawn ? 3 * n : 0, 0.0);
  if (!z_.empty()) rpy::fill_normal(ids_, z_, options_.integrator.seed, step_);
  // With rotation z_r from its own stream (bd/rotation_sampling.hpp), keyed alike.
  zr_.assign(rotation && drawn ? 3 * n : 0, 0.0);
  if (!zr_.empty()) rpy::fill_normal(ids_, zr_, options_.integrator.seed, step_, bd::kRotationNoiseStream);
  std::vector<double> next(3 * n);
  if (sac_) dx_.assign(3 * n, 0.0);
  StopWatch work;
  std::uint64_t refused = hydrodynamics_ ? displace_with_hydrodynamics(next) : displace_free_draining(next);
  std::vector<double> v_next;
  if (inertial_) refused = std::min(refused, displace_inertial(next, v_next));
  if (rotation && !hydrodynamics_) free_draining_rotation();
  if (split && !hydrodynamics_) free_draining_split();
  if (rotation) refused = std::min(refused, turn_angles());
  if (!hydrodynamics_) work_seconds_ += work.seconds();  // the hydrodynamic products are collective
  std::uint64_t lowest = kNoParticle;
  check_mpi(MPI_Allreduce(&refused, &lowest, 1, MPI_UINT64_T, MPI_MIN, comm_.get()), "MPI_Allreduce");
  if (lowest != kNoParticle) fail_blow_up(lowest, next);
  if (sac_) follow_carriers(next);  // after the guard, as bd::Integrator adds the carrier's step
  x_.swap(next);
  if (inertial_) v_.swap(v_next);  // kept only when the step is (bd::LangevinGroup::commit)
  // q <- exp(phi) q (bd::Integrator's update), and the sums of the rotation vectors (the log's).
  for (std::size_t i = 0; i < phi_.size() / 3; ++i) {
    bd::quaternion::rotate(std::span<double, 4>(q_.data() + 4 * i, 4), &phi_[3 * i]);
    for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) rotation_sum_[k] += phi_[k];
  }
  ++step_;
  ++stats_.steps;
  ++steps_since_rebuild_;
  // The next step's rebuild test over every rank's particles (or the fixed interval).
  const int interval = options_.neighbours.fixed_interval;
  // With the SAC scheme always the dynamic test: the halo must hold every carrier within R_A of an
  // owned adsorber (bd::Complexes' own list has the dynamic test whatever the options).
  const double limit2 = 0.25 * halo_->skin * halo_->skin;
  int moved = 0;
  for (std::size_t i = 0; i < n && !moved && (interval == 0 || sac_); ++i)
    moved = bd::device::moved_beyond_half_skin(i, x_.data(), list_reference_.data(), limit2) ? 1 : 0;
  int any = 0;
  check_mpi(MPI_Allreduce(&moved, &any, 1, MPI_INT, MPI_MAX, comm_.get()), "MPI_Allreduce");
  rebuild_due_ = (halo_->pairs || sac_) &&
                 ((interval > 0 && steps_since_rebuild_ >= static_cast<std::uint64_t>(interval)) || any != 0);
}

std::uint64_t DistributedBd::displace_free_draining(std::vector<double>& next) {
  const bd::device::EngineTables t = motion_tables(options_, forces_);
  const bd::device::MotionTables m{types_.data(), t.mobility.data(), t.sqrt_mobility.data(), t.radius.data(), t.dt,
                                   t.noise,       t.brownian,        t.max_displacement2,    t.seed,          step_};
  std::uint64_t refused = kNoParticle;
  for (std::size_t i = 0; i < ids_.size(); ++i) {
    if (inertial_type(options_.integrator, types_[i])) continue;  // the Langevin step moves it (displace_inertial)
    constexpr double kNoNoise[3] = {0.0, 0.0, 0.0};
    double dx[3];
    if (!bd::device::displacement_with(static_cast<std::uint32_t>(i), t.brownian ? &z_[3 * i] : kNoNoise, f_.data(), m,
                                       dx))
      refused = std::min(refused, ids_[i]);
    for (int c = 0; c < 3; ++c) next[3 * i + c] = x_[3 * i + c] + dx[c];
    if (sac_) std::copy(dx, dx + 3, &dx_[3 * i]);  // an adsorbed particle adds its carrier's
  }
  return refused;
}

std::uint64_t DistributedBd::displace_with_hydrodynamics(std::vector<double>& next) {
  // u = M F, w = M^{1/2} z over all ranks' particles (pse: u = M F + (noise / dt) M^{1/2} z in one
  // pass, z_ empty), then bd::Integrator's step and guard: dx = u dt + sqrt(2 kT dt) w, refused
  // beyond max_displacement x the radius (docs/theory/bd.md).
  const std::size_t n = ids_.size();
  radii_.resize(n);
  for (std::size_t i = 0; i < n; ++i) radii_[i] = forces_.types()[types_[i]].radius;
  u_.assign(3 * n, 0.0);
  w_.assign(z_.size(), 0.0);
  const double dt = options_.integrator.dt, noise = std::sqrt(2.0 * options_.integrator.kT * dt);
  const Hydrodynamics::FusedNoise fused{
      .scale = noise / dt, .seed = options_.integrator.seed, .step = step_, .ids = ids_, .total = global_n_};
  if (options_.integrator.rotation) {
    omega_.assign(3 * n, 0.0);
    wr_.assign(zr_.size(), 0.0);
    hydrodynamics_->grand_products(x_, radii_, {f_, torque_}, {z_, zr_}, ids_, {u_, omega_}, {w_, wr_});
  } else {
    hydrodynamics_->products(x_, radii_, f_, z_, fused, u_, w_);
  }
  const double frac2 = options_.integrator.max_displacement * options_.integrator.max_displacement;
  const bool split = options_.integrator.keep_split_displacements;
  dx_det_.resize(split ? 3 * n : 0);
  dx_brown_.resize(split ? 3 * n : 0);
  std::uint64_t refused = kNoParticle;
  for (std::size_t i = 0; i < n; ++i) {
    double d2 = 0.0;
    for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) {
      // bd::Integrator's dx and its split parts (u dt, noise w or 0), the same sum of them
      const double drift = u_[k] * dt, brownian = z_.empty() ? 0.0 : noise * w_[k], d = drift + brownian;
      if (split) {
        dx_det_[k] = drift;
        dx_brown_[k] = brownian;
      }
      next[k] = x_[k] + d;
      d2 += d * d;
    }
    if (!(d2 <= frac2 * radii_[i] * radii_[i])) refused = std::min(refused, ids_[i]);  // also catches NaN
  }
  return refused;
}

std::uint64_t DistributedBd::displace_inertial(std::vector<double>& next, std::vector<double>& v_next) {
  // bd::Integrator's step of its inertial particles (bd::LangevinGroup::displacements): the GJF
  // step on x = 0 gives the displacement exactly, x_{n+1} = x_n + dx, guarded as the others.
  const bd::IntegratorOptions& o = options_.integrator;
  const InertialSubset s = inertial_subset(o, types_, ids_);
  const std::size_t m = s.local.size();
  std::vector<double> f(3 * m), dx(3 * m, 0.0), v(3 * m);
  for (std::size_t k = 0; k < m; ++k)
    for (std::size_t c = 0; c < 3; ++c) {
      f[3 * k + c] = f_[3 * s.local[k] + c];
      v[3 * k + c] = v_[3 * s.local[k] + c];
    }
  bd::langevin_step({.dt = o.dt, .kT = o.kT, .seed = o.seed, .step = step_}, s.particles, s.index, f, dx, v);
  v_next = v_;
  const double frac2 = o.max_displacement * o.max_displacement;
  std::uint64_t refused = kNoParticle;
  for (std::size_t k = 0; k < m; ++k) {
    const std::size_t i = s.local[k];
    double d2 = 0.0;
    for (std::size_t c = 0; c < 3; ++c) {
      next[3 * i + c] = x_[3 * i + c] + dx[3 * k + c];
      if (sac_) dx_[3 * i + c] = dx[3 * k + c];  // the carrier's step, which its adsorbed particles take
      v_next[3 * i + c] = v[3 * k + c];
      d2 += dx[3 * k + c] * dx[3 * k + c];
    }
    const double radius = forces_.types()[types_[i]].radius;
    if (!(d2 <= frac2 * radius * radius)) refused = std::min(refused, ids_[i]);  // also catches NaN
  }
  return refused;
}

void DistributedBd::start_velocities(std::span<const double> given, std::span<const std::size_t> order) {
  // Given (0 for Brownian particles, checked), or bd::LangevinGroup::set_velocities' Maxwell draw
  // keyed by the global index.
  if (!given.empty()) {
    v_ = permuted(std::vector<double>(given.begin(), given.end()), order, 3);
    return;
  }
  const InertialSubset s = inertial_subset(options_.integrator, types_, ids_);
  std::vector<double> v(3 * s.local.size());
  bd::maxwell_velocities(options_.integrator.kT, options_.integrator.seed, s.particles, s.index, v);
  v_.assign(3 * ids_.size(), 0.0);
  for (std::size_t k = 0; k < s.local.size(); ++k)
    for (std::size_t c = 0; c < 3; ++c) v_[3 * s.local[k] + c] = v[3 * k + c];
}

double DistributedBd::kinetic_temperature() const {
  const InertialSubset s = inertial_subset(options_.integrator, types_, ids_);
  double mine[2] = {0.0, static_cast<double>(s.local.size())};  // sum of m |v|^2, inertial particles
  for (std::size_t k = 0; k < s.local.size(); ++k) {
    const double* v = v_.data() + 3 * s.local[k];
    mine[0] += s.particles[k].mass * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  }
  double all[2] = {0.0, 0.0};
  check_mpi(MPI_Allreduce(mine, all, 2, MPI_DOUBLE, MPI_SUM, comm_.get()), "MPI_Allreduce");
  return all[1] > 0.0 ? all[0] / (3.0 * all[1]) : 0.0;
}

void DistributedBd::free_draining_rotation() {
  // The serial engine's operator is diagonal, each particle's values its own: its rotational
  // mobility per type, 1 / (8 pi eta a^3) and its square root, rpy::FreeDrainingMobility's values
  // (rpy::sphere_mobility), times the torque and z_r as its products take them, so they are the
  // serial ones bit for bit.
  const std::size_t ntypes = forces_.types().size();
  std::vector<rpy::SphereMobility> mobility(ntypes);
  for (std::size_t t = 0; t < ntypes; ++t)
    mobility[t] = rpy::sphere_mobility(forces_.types()[t].radius, options_.viscosity);
  omega_.resize(torque_.size());
  wr_.resize(zr_.size());
  for (std::size_t i = 0; i < ids_.size(); ++i)
    for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) {
      omega_[k] = mobility[types_[i]].rotation * torque_[k];
      if (!zr_.empty()) wr_[k] = mobility[types_[i]].sqrt_rotation * zr_[k];
    }
}

void DistributedBd::free_draining_split() {
  // rpy::FreeDrainingMobility's u = mu F and w = sqrt(mu) z with the device stage's per-type mu
  // (the same values, bd::device::make_motion_tables), split as bd::Integrator splits dx = u dt +
  // noise w: bd::device::displacement_with's terms, so their sum is its dx bit for bit.
  const bd::device::EngineTables t = motion_tables(options_, forces_);
  const std::size_t n = ids_.size();
  dx_det_.assign(3 * n, 0.0);
  dx_brown_.assign(3 * n, 0.0);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) {
      dx_det_[k] = t.mobility[types_[i]] * f_[k] * t.dt;
      if (t.brownian) dx_brown_[k] = t.noise * (t.sqrt_mobility[types_[i]] * z_[k]);
    }
}

std::uint64_t DistributedBd::turn_angles() {
  // bd::Integrator's phi = omega dt + sqrt(2 kT dt) w_r and its guard on |phi| (docs/theory/bd.md Sec. 7).
  const double dt = options_.integrator.dt, noise = std::sqrt(2.0 * options_.integrator.kT * dt);
  const double frac2 = options_.integrator.max_displacement * options_.integrator.max_displacement;
  const bool brownian = !zr_.empty();
  std::uint64_t refused = kNoParticle;
  phi_.resize(omega_.size());
  for (std::size_t i = 0; i < ids_.size(); ++i) {
    double turn2 = 0.0;
    for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) {
      phi_[k] = omega_[k] * dt + (brownian ? noise * wr_[k] : 0.0);
      turn2 += phi_[k] * phi_[k];
    }
    if (!(turn2 <= frac2)) refused = std::min(refused, ids_[i]);  // also catches NaN
  }
  return refused;
}

void DistributedBd::fail_blow_up(std::uint64_t id, std::span<const double> next) const {
  // The rank that owns the particle words the error (bd::Integrator's), every rank throws it.
  std::optional<Error> problem;
  const auto it = std::lower_bound(ids_.begin(), ids_.end(), id);
  if (it != ids_.end() && *it == id) {
    const auto i = static_cast<std::size_t>(it - ids_.begin());
    double d2 = 0.0, f2 = 0.0;
    for (int c = 0; c < 3; ++c) {
      const double d = next[3 * i + c] - x_[3 * i + c];
      d2 += d * d;
      f2 += f_[3 * i + c] * f_[3 * i + c];
    }
    const double radius = forces_.types()[types_[i]].radius, limit = options_.integrator.max_displacement;
    double turn2 = 0.0, t2 = 0.0;
    for (std::size_t k = 3 * i; k < 3 * i + 3 && !phi_.empty(); ++k) {
      turn2 += phi_[k] * phi_[k];
      t2 += torque_[k] * torque_[k];
    }
    std::ostringstream msg;
    msg << kWhere << ": blow-up at step " << step_ << ": particle " << id;
    if (!phi_.empty() && !(std::sqrt(turn2) <= limit) && std::sqrt(d2) <= limit * radius)
      msg << " would turn by " << std::sqrt(turn2) << " rad > max_displacement (" << limit
          << ") in one step (|torque| = " << std::sqrt(t2) << ")";
    else
      msg << " would move " << std::sqrt(d2) << " > max_displacement (" << limit << ") x radius " << radius
          << " in one step (|force| = " << std::sqrt(f2) << ")";
    msg << "; reduce dt or check the forces. State kept at the last good step";
    problem = Error(ErrorCode::numerical_failure, msg.str());
  }
  comm_.agree(problem);
}

std::array<double, 2> DistributedBd::rotation_moments() const {
  require(options_.integrator.rotation, ErrorCode::invalid_argument, kWhere, "rotation_moments needs rotation");
  const std::array<double, 2> mine = bd::rotation_moment_sums(q_, reference_q_, rotation_sum_);
  std::array<double, 2> all{};
  check_mpi(MPI_Allreduce(mine.data(), all.data(), 2, MPI_DOUBLE, MPI_SUM, comm_.get()), "MPI_Allreduce");
  const auto n = static_cast<double>(global_n_);
  return {all[0] / n, all[1] / n};
}

bd::Checkpoint DistributedBd::checkpoint(int root) const {
  require(root >= 0 && root < comm_.size(), ErrorCode::invalid_argument, kWhere,
          "checkpoint root " + std::to_string(root) + " is not a rank of the communicator");
  // id, type, x (3), reference (3); with rotation q (4), q at step 0 (4), summed rotation vector
  // (3); with inertial particles v (3)
  const bool rotation = options_.integrator.rotation;
  const std::size_t values = rotation ? 8 + kRotationValues : inertial_ ? 11 : 8;
  std::vector<double> packed;
  packed.reserve(values * ids_.size());
  for (std::size_t i = 0; i < ids_.size(); ++i) {
    packed.insert(packed.end(), {static_cast<double>(ids_[i]), static_cast<double>(types_[i])});
    packed.insert(packed.end(), &x_[3 * i], &x_[3 * i + 3]);
    packed.insert(packed.end(), &reference_[3 * i], &reference_[3 * i + 3]);
    if (rotation) pack_rotation(packed, q_, reference_q_, rotation_sum_, i);
    if (inertial_) packed.insert(packed.end(), &v_[3 * i], &v_[3 * i + 3]);
  }
  std::vector<std::vector<double>> send(comm_.size());
  send[root] = std::move(packed);
  const std::vector<double> all = detail::alltoallv(comm_, send, kWhere, "the checkpoint's particles");
  bd::Checkpoint c;
  if (comm_.rank() != root) return c;
  const std::size_t n = global_n_;
  c.step = step_;
  c.seed = options_.integrator.seed;
  c.dt = options_.integrator.dt;
  c.positions.resize(3 * n);
  c.reference_positions.resize(3 * n);
  c.types.resize(n);
  if (rotation) {
    c.orientations.resize(4 * n);
    c.reference_orientations.resize(4 * n);
    c.rotation_vectors.resize(3 * n);
  }
  if (inertial_) c.velocities.resize(3 * n);
  for (std::size_t k = 0; k < n; ++k) {
    const double* v = &all[values * k];
    const auto id = static_cast<std::size_t>(v[0]);
    c.types[id] = static_cast<std::uint32_t>(v[1]);
    for (int a = 0; a < 3; ++a) {
      c.positions[3 * id + a] = v[2 + a];
      c.reference_positions[3 * id + a] = v[5 + a];
    }
    if (rotation) unpack_rotation(v + 8, id, c.orientations, c.reference_orientations, c.rotation_vectors);
    if (inertial_) std::copy(v + 8, v + 11, &c.velocities[3 * id]);
  }
  return c;
}

DistributedBd restart_distributed_bd(MPI_Comm comm_handle, bd::ForceField forces, rpy::Geometry geometry,
                                     DistributedBdOptions options, const bd::Checkpoint& checkpoint, int root) {
  const Communicator comm(comm_handle);
  require(root >= 0 && root < comm.size(), ErrorCode::invalid_argument, kWhere,
          "restart root " + std::to_string(root) + " is not a rank of the communicator");
  comm.run([&] {
    if (comm.rank() != root) return;
    // bd::restart_bd's test: velocities exactly when the options make some of its particles inertial.
    const bool langevin = std::any_of(checkpoint.types.begin(), checkpoint.types.end(),
                                      [&](std::uint32_t t) { return inertial_type(options.integrator, t); });
    require(langevin != checkpoint.velocities.empty(), ErrorCode::invalid_argument, kWhere,
            "the options' inertial (Langevin) types disagree with the checkpoint's velocities");
    require(checkpoint.orientations.empty() != options.integrator.rotation, ErrorCode::invalid_argument, kWhere,
            options.integrator.rotation ? "the options have rotation but the checkpoint holds no orientations"
                                        : "the checkpoint holds orientations but the options have no rotation");
    const std::size_t n = checkpoint.types.size();
    require(checkpoint.orientations.empty() ||
                (checkpoint.orientations.size() == 4 * n && checkpoint.reference_orientations.size() == 4 * n &&
                 checkpoint.rotation_vectors.size() == 3 * n),
            ErrorCode::invalid_input, kWhere,
            "the checkpoint's orientations, reference orientations, rotation vectors and types disagree on N");
    require(checkpoint.velocities.empty() || checkpoint.velocities.size() == 3 * n, ErrorCode::invalid_input, kWhere,
            "the checkpoint's velocities and types disagree on N");
    require(checkpoint.seed == options.integrator.seed && checkpoint.dt == options.integrator.dt,
            ErrorCode::invalid_argument, kWhere, "the checkpoint's seed and dt differ from the options'");
    require(checkpoint.positions.size() == 3 * checkpoint.types.size() &&
                checkpoint.reference_positions.size() == checkpoint.positions.size(),
            ErrorCode::invalid_input, kWhere, "the checkpoint's positions and types disagree on N");
  });
  std::uint64_t header[3] = {checkpoint.types.size(), checkpoint.step, checkpoint.velocities.empty() ? 0u : 1u};
  check_mpi(MPI_Bcast(header, 3, MPI_UINT64_T, root, comm.get()), "MPI_Bcast");
  // Blocks of global indices: rank r gets [r N / P, (r + 1) N / P).
  const auto p = static_cast<std::uint64_t>(comm.size()), total = header[0];
  const auto first = [&](std::uint64_t r) { return (r * total) / p; };
  // type, x (3), reference (3); with rotation q (4), q at step 0 (4), summed rotation vector (3);
  // with velocities v (3)
  const bool rotation = options.integrator.rotation, velocities = header[2] != 0;
  const std::size_t values = rotation ? 7 + kRotationValues : velocities ? 10 : 7;
  std::vector<std::vector<double>> blocks(comm.size());
  for (std::uint64_t r = 0; r < blocks.size() && comm.rank() == root; ++r) {
    for (std::uint64_t i = first(r); i < first(r + 1); ++i) {
      blocks[r].push_back(static_cast<double>(checkpoint.types[i]));
      blocks[r].insert(blocks[r].end(), &checkpoint.positions[3 * i], &checkpoint.positions[3 * i + 3]);
      blocks[r].insert(blocks[r].end(), &checkpoint.reference_positions[3 * i],
                       &checkpoint.reference_positions[3 * i + 3]);
      if (rotation)
        pack_rotation(blocks[r], checkpoint.orientations, checkpoint.reference_orientations,
                      checkpoint.rotation_vectors, i);
      if (velocities)
        blocks[r].insert(blocks[r].end(), &checkpoint.velocities[3 * i], &checkpoint.velocities[3 * i + 3]);
    }
  }
  const std::vector<double> mine = detail::alltoallv(comm, blocks, kWhere, "the checkpoint's particles");
  const auto r = static_cast<std::uint64_t>(comm.rank());
  BdShare share;
  const std::size_t count = first(r + 1) - first(r);
  if (rotation) {
    share.orientations.resize(4 * count);
    share.reference_orientations.resize(4 * count);
    share.rotation_vectors.resize(3 * count);
  }
  for (std::uint64_t i = first(r); i < first(r + 1); ++i) {
    const double* v = &mine[values * (i - first(r))];
    share.types.push_back(static_cast<std::uint32_t>(v[0]));
    share.positions.insert(share.positions.end(), v + 1, v + 4);
    share.reference_positions.insert(share.reference_positions.end(), v + 4, v + 7);
    share.ids.push_back(i);
    if (rotation)
      unpack_rotation(v + 7, i - first(r), share.orientations, share.reference_orientations, share.rotation_vectors);
    if (velocities) share.velocities.insert(share.velocities.end(), v + 7, v + 10);
  }
  return DistributedBd(comm_handle, std::move(forces), geometry, std::move(options), std::move(share), header[1]);
}

}  // namespace rpyfmm::mpi
