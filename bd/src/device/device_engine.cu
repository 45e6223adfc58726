// rpyfmm::bd::device — DeviceEngine: the host launcher's step (host_engine.cpp) with each stage a
// CUDA kernel of one thread per particle (slot, cell) calling the same host-device function.
// The positions stay on the device; per step the host reads one StepStatus (the failure slots
// and the next step's rebuild test, as the update kernel of Tran et al. (2015) sets its flag, Algorithm
// 1, lines 14-16), and per rebuild the grid bounds and the number of pairs. Scans by CUB; the
// kernels are in device_kernels.cuh.
// Compiled with --fmad=false: the kernels' a * b + c stay unfused, as on the host, so that
// host and device agree bit for bit but for the device's own exp and log (DLVO, FENE).
#include <cuda_runtime.h>

#include <algorithm>
#include <cub/device/device_scan.cuh>
#include <string>
#include <utility>

#include "cuda_buffer.cuh"
#include "cuda_events.cuh"
#include "device_kernels.cuh"
#include "engine_tables.hpp"
#include "rebuild_schedule.hpp"
#include "rpyfmm/bd/device/device_engine.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"
#include "step_status.hpp"

namespace rpyfmm::bd::device {

namespace {

using namespace kernels;

void check_launch(const char* what) {
  cuda_check(cudaGetLastError(), what);
}

/// Why no device is usable, or empty when one is.
std::string unavailable_reason() {
  int count = 0;
  const cudaError_t e = cudaGetDeviceCount(&count);
  if (e != cudaSuccess) {
    (void)cudaGetLastError();
    return std::string("cudaGetDeviceCount: ") + cudaGetErrorString(e);
  }
  if (count == 0) return "no CUDA device";
  cudaFuncAttributes attributes{};
  const cudaError_t image = cudaFuncGetAttributes(&attributes, forces_kernel);
  (void)cudaGetLastError();
  if (image != cudaSuccess)
    return std::string("no kernel image for this device (CMAKE_CUDA_ARCHITECTURES): ") + cudaGetErrorString(image);
  return {};
}

}  // namespace

struct DeviceEngine::Impl {
  EngineTables t;
  std::uint32_t n = 0;
  int device = 0;  // the CUDA ordinal current at construction
  std::uint64_t step = 0;
  RebuildSchedule schedule{0.0, 0};
  bool rebuilt = false;
  std::uint64_t pairs = 0;  // entries of the rows
  bool along_grid = false;  // order holds the slots of the last build
  // tables
  DeviceBuffer<std::uint32_t> type, bond_begin;
  DeviceBuffer<PairTerm> pair_terms;
  DeviceBuffer<BondEntry> bonds;
  DeviceBuffer<BondPotential> bond_potentials;
  DeviceBuffer<double> external, list_rl2, mobility, sqrt_mobility, radius;
  // state
  DeviceBuffer<double> x, x_next, reference, f, energy, xs, bounds;
  DeviceBuffer<std::uint64_t> offsets;
  DeviceBuffer<std::uint32_t> indices, cell_of, rank, count, start, order, ts;
  DeviceBuffer<StepStatus> status;
  DeviceBuffer<unsigned char> scratch;
  StageEvents marks;
  StageTimes times{{"neighbours", 0.0}, {"forces", 0.0}, {"update", 0.0}};
  // PSE (EngineOptions::pse): the operator, its velocities (input order) and the last report.
  rpy::pse::PseRpyCuda* pse = nullptr;
  DeviceBuffer<double> u;
  std::optional<DriftNoiseReport> products;

  /// The PSE operator of `options` as PseRpyCuda, placed at the initial positions (its plan; the
  /// steps move it on the device). Throws naming the operator when it is another one.
  void attach_pse(const EngineOptions& options, std::span<const double> positions) {
    auto* cuda = dynamic_cast<rpy::pse::PseRpyCuda*>(options.pse);
    require(cuda != nullptr, ErrorCode::not_supported, "bd device engine",
            "PSE on the CUDA engine runs the operator 'pse-cuda' (PseRpyCuda, its device entry points), not '" +
                options.pse->name() + "'");
    pse = cuda;
    cuda->set_positions(positions, particle_radii(t));
    u.reserve(3ull * n);
    times["plan"] = 0.0;
    times["drift"] = 0.0;
  }

  /// The CPU engine's steps 3 and 4 (Integrator::step) on device arrays: the operator moved to
  /// the positions x, then U = M F + sqrt(2 kT dt) / dt M^{1/2} z in one pass (U = M F without
  /// noise). Both calls synchronise: timed on the host clock.
  void hydrodynamic_velocities() {
    StopWatch watch;
    pse->set_positions_device(x.get());
    times["plan"] += watch.seconds();
    watch.restart();
    DriftNoiseReport r;
    if (t.brownian) {
      r.sqrt = pse->apply_with_noise_device(f.get(), t.noise / t.dt, t.seed, step, u.get());
      r.mobility_products = r.sqrt.operator_applications;
    } else {
      pse->apply_device(f.get(), u.get());
      r.mobility_products = 1;
    }
    r.seconds_drift = watch.seconds();
    products = r;
    times["drift"] += r.seconds_drift;
  }

  void upload_tables() {
    type.upload(t.type);
    bond_begin.upload(t.bond_begin);
    pair_terms.upload(t.pairs);
    bonds.upload(t.bonds);
    bond_potentials.upload(t.bond_potentials);
    external.upload(t.external);
    list_rl2.upload(t.list_rl2);
    mobility.upload(t.mobility);
    sqrt_mobility.upload(t.sqrt_mobility);
    radius.upload(t.radius);
  }

  /// offsets[1..n] hold the row lengths: make them offsets, return the number of entries.
  std::uint64_t scan_rows() {
    std::size_t bytes = 0;
    cuda_check(cub::DeviceScan::InclusiveSum(nullptr, bytes, offsets.get() + 1, offsets.get() + 1, n), "row scan");
    scratch.reserve(bytes);
    cuda_check(cub::DeviceScan::InclusiveSum(scratch.get(), bytes, offsets.get() + 1, offsets.get() + 1, n),
               "row scan");
    std::uint64_t total = 0;
    cuda_check(cudaMemcpy(&total, offsets.get() + n, sizeof total, cudaMemcpyDeviceToHost), "row count");
    indices.reserve(std::max<std::uint64_t>(total, 1));
    return total;
  }

  CellGrid grid() {
    double lo[3] = {0.0, 0.0, 0.0}, hi[3] = {0.0, 0.0, 0.0};
    if (!t.image.periodic) {
      bounds.reserve(6 * kBoundsBlocks);
      bounds_kernel<<<kBoundsBlocks, kThreads>>>(n, x.get(), bounds.get());
      check_launch("bounds kernel");
      const std::vector<double> b = bounds.download(6 * kBoundsBlocks);
      for (int c = 0; c < 3; ++c) {
        lo[c] = b[c];
        hi[c] = b[3 + c];
        for (unsigned k = 1; k < kBoundsBlocks; ++k) {
          lo[c] = std::min(lo[c], b[6 * k + c]);
          hi[c] = std::max(hi[c], b[6 * k + 3 + c]);
        }
      }
    }
    return make_cell_grid(lo, hi, t.list_radius(), n, t.image.periodic, t.image.box);
  }

  void rows_from_all_pairs(const ListRadii& radii, RowsBuild rows) {
    count_all_kernel<<<blocks_for(n), kThreads>>>(n, x.get(), type.get(), t.image, radii, rows);
    check_launch("row count kernel");
    pairs = scan_rows();
    rows.indices = indices.get();
    fill_all_kernel<<<blocks_for(n), kThreads>>>(n, x.get(), type.get(), t.image, radii, rows);
    check_launch("row fill kernel");
  }

  /// Counting sort into cells: each cell's first slot (exclusive scan of the counts).
  CellBins bin(const CellGrid& g) {
    const std::uint64_t cells = g.cells();
    for (auto* b : {&cell_of, &rank, &order, &ts}) b->reserve(n);
    count.reserve(cells + 1);
    start.reserve(cells + 1);
    xs.reserve(3ull * n);
    cuda_check(cudaMemset(count.get(), 0, (cells + 1) * sizeof(std::uint32_t)), "cudaMemset");
    const CellBins bins{cell_of.get(), rank.get(), count.get(), start.get(), order.get()};
    bin_kernel<<<blocks_for(n), kThreads>>>(n, x.get(), g, bins);
    check_launch("bin kernel");
    std::size_t bytes = 0;
    const auto items = static_cast<std::int64_t>(cells + 1);
    cuda_check(cub::DeviceScan::ExclusiveSum(nullptr, bytes, count.get(), start.get(), items), "cell scan");
    scratch.reserve(bytes);
    cuda_check(cub::DeviceScan::ExclusiveSum(scratch.get(), bytes, count.get(), start.get(), items), "cell scan");
    place_kernel<<<blocks_for(n), kThreads>>>(n, bins);
    check_launch("place kernel");
    sort_cells_kernel<<<blocks_for(cells), kThreads>>>(cells, bins);
    check_launch("cell sort kernel");
    gather_kernel<<<blocks_for(n), kThreads>>>(n, x.get(), type.get(), g, bins, xs.get(), ts.get());
    check_launch("gather kernel");
    return bins;
  }

  void rows_from_cells(const CellGrid& g, const ListRadii& radii, RowsBuild rows) {
    const CellBins bins = bin(g);
    const SlotView slots{bins.order, bins.start, bins.cell_of, xs.get(), ts.get()};
    count_cells_kernel<<<blocks_for(n), kThreads>>>(n, g, slots, radii, rows);
    check_launch("row count kernel");
    pairs = scan_rows();
    rows.indices = indices.get();
    fill_cells_kernel<<<blocks_for(n), kThreads>>>(n, g, slots, radii, rows);
    check_launch("row fill kernel");
    along_grid = true;
  }

  void build_lists() {
    cuda_check(cudaMemcpy(reference.get(), x.get(), 3ull * n * sizeof(double), cudaMemcpyDeviceToDevice),
               "reference positions");
    cuda_check(cudaMemset(offsets.get(), 0, (n + 1ull) * sizeof(std::uint64_t)), "cudaMemset");
    pairs = 0;
    along_grid = false;
    if (t.cutoff == 0.0) return;
    const CellGrid g = grid();
    const ListRadii radii{list_rl2.get(), t.ntypes};
    const RowsBuild rows{offsets.get(), nullptr};
    if (t.rows_from_all_pairs(g)) {
      rows_from_all_pairs(radii, rows);
    } else {
      rows_from_cells(g, radii, rows);
    }
  }

  [[nodiscard]] ForceTables force_tables() {
    return {t.ntypes, type.get(),       pair_terms.get(), t.has_pairs,           external.get(),
            t.trap,   bond_begin.get(), bonds.get(),      bond_potentials.get(), t.image};
  }

  void step_once() {
    marks.mark(0);
    rebuilt = schedule.next_step();
    if (rebuilt) build_lists();
    marks.mark(1);
    // Every slot kNone (all bits set): a memset, no copy from the host.
    static_assert(sizeof(StepStatus) == 4 * sizeof(std::uint64_t) && kNone == ~std::uint64_t{0});
    cuda_check(cudaMemsetAsync(status.get(), 0xFF, sizeof(StepStatus)), "step status");
    StepStatus* s = status.get();
    const RowsView rows{offsets.get(), indices.get()};
    const std::uint32_t* slots = along_grid ? order.get() : nullptr;
    forces_kernel<<<blocks_for(n), kThreads>>>(n, slots, x.get(), force_tables(), rows,
                                               ForceOutput{f.get(), energy.get(), &s->bad_pair, &s->bad_bond});
    check_launch("forces kernel");
    marks.mark(2);
    if (pse != nullptr) hydrodynamic_velocities();
    marks.mark(3);
    const MotionTables m{type.get(), mobility.get(), sqrt_mobility.get(), radius.get(), t.dt,
                         t.noise,    t.brownian,     t.max_displacement2, t.seed,       step};
    const MotionOutput out{x_next.get(), schedule.dynamic() ? reference.get() : nullptr, t.rebuild_limit2(),
                           &s->bad_move, &s->moved};
    if (pse != nullptr) {
      advance_with_kernel<<<blocks_for(n), kThreads>>>(n, slots, x.get(), u.get(), m, out);
    } else {
      advance_kernel<<<blocks_for(n), kThreads>>>(n, slots, x.get(), f.get(), m, out);
    }
    check_launch("advance kernel");
    marks.mark(4);
    StepStatus found;
    cuda_check(cudaMemcpy(&found, status.get(), sizeof found, cudaMemcpyDeviceToHost), "step status");
    times["neighbours"] += marks.seconds(0, 1);
    times["forces"] += marks.seconds(1, 2);
    times["update"] += marks.seconds(3, 4);
    throw_if_failed(found, step);
    swap(x, x_next);
    schedule.set_moved(found.moved != kNone);
    ++step;
  }
};

bool DeviceEngine::device_available() {
  return unavailable_reason().empty();
}

DeviceEngine::DeviceEngine(const ForceField& forces, std::vector<std::uint32_t> types, rpy::Geometry geometry,
                           const EngineOptions& options, std::span<const double> positions, std::uint64_t first_step) {
  // Before any CUDA call of Impl (its events): without a device, the reason, not the call's error.
  const std::string reason = unavailable_reason();
  require(reason.empty(), ErrorCode::not_supported, "bd device engine", "no usable CUDA device: " + reason);
  impl_ = std::make_unique<Impl>();
  Impl& d = *impl_;
  cuda_check(cudaGetDevice(&d.device), "cudaGetDevice");
  d.t = make_engine_tables(forces, types, geometry, options);
  check_positions(positions, d.t.n);
  d.n = static_cast<std::uint32_t>(d.t.n);
  d.step = first_step;
  d.schedule = RebuildSchedule(d.t.cutoff, d.t.fixed_interval);
  d.upload_tables();
  d.x.upload(std::vector<double>(positions.begin(), positions.end()));
  for (auto* b : {&d.x_next, &d.reference, &d.f}) b->reserve(3ull * d.n);
  d.energy.reserve(d.n);
  d.offsets.reserve(d.n + 1ull);
  d.indices.reserve(1);
  d.status.reserve(1);
  // No step yet: no forces, no energy, empty rows (the host launcher's state).
  cuda_check(cudaMemset(d.f.get(), 0, 3ull * d.n * sizeof(double)), "cudaMemset");
  cuda_check(cudaMemset(d.energy.get(), 0, d.n * sizeof(double)), "cudaMemset");
  cuda_check(cudaMemset(d.offsets.get(), 0, (d.n + 1ull) * sizeof(std::uint64_t)), "cudaMemset");
  if (options.pse != nullptr) d.attach_pse(options, positions);
}

DeviceEngine::~DeviceEngine() = default;

void DeviceEngine::step() {
  impl_->step_once();
}

void DeviceEngine::run(std::uint64_t count) {
  for (std::uint64_t k = 0; k < count; ++k) impl_->step_once();
}

std::vector<double> DeviceEngine::positions() const {
  return impl_->x.download(3ull * impl_->n);
}

std::vector<double> DeviceEngine::forces() const {
  return impl_->f.download(3ull * impl_->n);
}

const double* DeviceEngine::device_positions() const {
  return impl_->x.get();
}

const double* DeviceEngine::device_forces() const {
  return impl_->f.get();
}

int DeviceEngine::device() const {
  return impl_->device;
}

double DeviceEngine::potential_energy() const {
  double energy = 0.0;
  for (const double e : impl_->energy.download(impl_->n)) energy += e;
  return energy;
}

NeighbourRows DeviceEngine::neighbour_rows() const {
  return {impl_->offsets.download(impl_->n + 1ull), impl_->indices.download(impl_->pairs)};
}

std::uint64_t DeviceEngine::step_count() const {
  return impl_->step;
}

std::size_t DeviceEngine::rebuilds() const {
  return impl_->schedule.rebuilds();
}

bool DeviceEngine::last_step_rebuilt() const {
  return impl_->rebuilt;
}

StageTimes DeviceEngine::stage_times() const {
  return impl_->times;
}

std::optional<DriftNoiseReport> DeviceEngine::mobility_report() const {
  return impl_->products;
}

}  // namespace rpyfmm::bd::device
