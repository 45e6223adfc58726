// rpyfmm — the wave-space part of DistributedPseRpy on FFTW-MPI slabs (pse_slab_wave.hpp).
//
// [PSE] eq. 19: U = D^-1 F^-1 B F D F. Spreading D and interpolation D^-1 are local to the x planes
// a particle's window covers, so each particle's position (once) and force (every product) go to
// the ranks owning those planes; each owner spreads onto its planes only and returns its planes'
// share of the interpolated velocity. FFTW-MPI transforms the slabs (non-transposed: the spectrum
// keeps the grid's slab of x planes), and the scaling B of each mode is the serial one
// (kernels_common.hpp's scale_mode_with, with the serial operator's c(k) table restricted to the
// slab). The window weights come from the serial formulas (window_weights_recurrence) on the
// positions wrapped as the serial operator wraps them; the grid sums are added in another order.
// With rotation the torques travel with the forces, are spread onto a second set of slabs, and both
// spectra are scaled mode by mode by the serial scale_rotation_mode (rotation_modes.hpp), whose
// factors g(k), sinc and s/2 the slab tabulates for its modes once.
// [PSE]: Fiore, Balboa Usabiaga, Donev & Swan, J. Chem. Phys. 146, 124116 (2017).
#include "pse_slab_wave.hpp"

#include <fftw3-mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <mutex>
#include <numbers>

#include "index_exchange.hpp"
#include "pse/kernels_common.hpp"
#include "pse/wave_space.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::mpi::detail {
namespace {

constexpr const char* kWhere = "DistributedPseRpy";

void init_fftw_mpi() {
  static std::once_flag once;
  std::call_once(once, [] { fftw_mpi_init(); });
}

/// This rank's slab of an n[0] x n[1] x n[2] grid as FFTW-MPI distributes it
/// (fftw_mpi_local_size_3d of the n[2] / 2 + 1 complex points per z line, in place): its planes
/// [x0, x0 + nx) and the complex values between components, FFTW's local size (with the planes and
/// padding it asks for) rounded up to a multiple of 4 (64-byte aligned components).
struct SlabLayout {
  std::ptrdiff_t x0 = 0, nx = 0;
  std::size_t comp = 0;
};

SlabLayout slab_layout(const Communicator& comm, const std::array<int, 3>& n) {
  init_fftw_mpi();
  SlabLayout s;
  const std::ptrdiff_t alloc = fftw_mpi_local_size_3d(n[0], n[1], n[2] / 2 + 1, comm.get(), &s.nx, &s.x0);
  s.comp = (static_cast<std::size_t>(std::max<std::ptrdiff_t>(alloc, 1)) + 3) / 4 * 4;
  return s;
}

}  // namespace

std::size_t SlabWaveSpace::memory_bytes(const Communicator& comm, const rpy::pse::PseParameters& p) {
  const SlabLayout s = slab_layout(comm, p.grid);
  // Three in-place components of `comp` complex values (16 bytes), and c(k) of the slab's modes.
  const std::size_t modes = static_cast<std::size_t>(s.nx) * static_cast<std::size_t>(p.grid[1]) *
                            static_cast<std::size_t>(p.grid[2] / 2 + 1);
  return 3 * s.comp * sizeof(fftw_complex) + modes * sizeof(double);
}

struct SlabWaveSpace::Slab {
  const Communicator& comm;
  rpy::pse::PseParameters p;
  std::array<int, 3> n{}, P{};
  int nzh = 0;                    // n_z / 2 + 1 complex points per z line
  std::ptrdiff_t x0 = 0, nx = 0;  // this rank's planes [x0, x0 + nx)
  std::vector<int> plane_owner;   // rank of every x plane
  std::size_t comp = 0;           // complex values between components (a multiple of 4: 64-byte aligned)
  fftw_complex* data = nullptr;   // 3 components, each the slab in place (real, padded z; or spectrum)
  // apply_rotation's torque (then angular velocity) components, laid out as `data`, and the
  // rotational factors of the slab's modes (rotation_modes.hpp): allocated by the first product
  // with torques.
  fftw_complex* rotation_data = nullptr;
  rpy::pse::detail::RotationModeConstants rotation_constants{};
  std::vector<rpy::pse::detail::RotationModeFactors> rotation_factors;
  fftw_plan forward = nullptr, backward = nullptr;
  rpy::pse::detail::ModeGeometry modes{};
  std::vector<double> ck;  // c(k) of the slab's modes
  double c3 = 0.0, dv = 0.0;
  // The particles whose windows touch this slab: wrapped window starts and 1D weights (P_x + P_y +
  // P_z each), in the order received.
  IndexExchange exchange;
  std::vector<int> start;
  std::vector<double> weights;

  Slab(const Communicator& c, const rpy::pse::PseParameters& params)
      : comm(c), p(params), n(params.grid), P(params.support) {}
  ~Slab() {
    if (forward != nullptr) fftw_destroy_plan(forward);
    if (backward != nullptr) fftw_destroy_plan(backward);
    fftw_free(data);
    fftw_free(rotation_data);
  }

  // Component c of the three at `base` (data or rotation_data) as real slab and as spectrum.
  [[nodiscard]] double* component(fftw_complex* base, int c) const {
    return reinterpret_cast<double*>(base + comp * static_cast<std::size_t>(c));
  }
  [[nodiscard]] const double* component(const fftw_complex* base, int c) const {
    return reinterpret_cast<const double*>(base + comp * static_cast<std::size_t>(c));
  }
  [[nodiscard]] double* component(int c) const { return component(data, c); }
  [[nodiscard]] fftw_complex* spectrum(fftw_complex* base, int c) const {
    return base + comp * static_cast<std::size_t>(c);
  }
  [[nodiscard]] bool owns(int gx) const { return gx >= x0 && gx < x0 + nx; }
  // Index of real grid point (gx, gy, gz) in a component (gx in the slab; z padded to 2 nzh).
  [[nodiscard]] std::size_t real_index(int gx, int gy, int gz) const {
    return (static_cast<std::size_t>(gx - x0) * static_cast<std::size_t>(n[1]) + static_cast<std::size_t>(gy)) *
               static_cast<std::size_t>(2 * nzh) +
           static_cast<std::size_t>(gz);
  }

  void plan(const std::array<double, 3>& box, double viscosity);
  [[nodiscard]] std::vector<std::vector<std::uint32_t>> destinations(std::span<const double> x) const;
  void windows(const std::vector<double>& received);
  void spread(const std::vector<double>& loads, std::size_t width, std::size_t at, fftw_complex* base);
  void transform_forward(fftw_complex* base);
  void scale(bool deterministic, const rpy::pse::detail::NoiseKey* noise, double noise_scale);
  void allocate_rotation();
  void scale_rotation(bool deterministic, const rpy::pse::detail::NoiseKey* noise, double noise_scale);
  void interpolate(const fftw_complex* base, std::vector<double>& shares, std::size_t width, std::size_t at) const;
  void to_particles(std::span<fftw_complex* const> grids, std::span<double* const> outs, std::size_t particles,
                    bool accumulate);
};

void SlabWaveSpace::Slab::plan(const std::array<double, 3>& box, double viscosity) {
  nzh = n[2] / 2 + 1;
  const SlabLayout layout = slab_layout(comm, n);
  x0 = layout.x0;
  nx = layout.nx;
  comp = layout.comp;
  std::array<std::int64_t, 2> mine{x0, nx};
  std::vector<std::int64_t> all(2 * static_cast<std::size_t>(comm.size()));
  check_mpi(MPI_Allgather(mine.data(), 2, MPI_INT64_T, all.data(), 2, MPI_INT64_T, comm.get()), "MPI_Allgather");
  plane_owner.assign(static_cast<std::size_t>(n[0]), 0);
  for (std::size_t r = 0; r < static_cast<std::size_t>(comm.size()); ++r)
    for (std::int64_t gx = all[2 * r]; gx < all[2 * r] + all[2 * r + 1]; ++gx)
      plane_owner[static_cast<std::size_t>(gx)] = static_cast<int>(r);
  comm.run([&] {
    data = fftw_alloc_complex(3 * comp);
    require(data != nullptr, ErrorCode::out_of_memory, kWhere, "could not allocate the FFT slabs");
  });
  // The plans are collective over the communicator (FFTW_ESTIMATE: the same algorithm in every
  // run, so repeated products agree bit for bit).
  forward = fftw_mpi_plan_dft_r2c_3d(n[0], n[1], n[2], component(0), data, comm.get(), FFTW_ESTIMATE);
  backward = fftw_mpi_plan_dft_c2r_3d(n[0], n[1], n[2], data, component(0), comm.get(), FFTW_ESTIMATE);
  comm.run([&] {
    require(forward != nullptr && backward != nullptr, ErrorCode::numerical_failure, kWhere,
            "FFTW-MPI could not create the plans");
  });
  ck = rpy::pse::detail::wave_scaling_table(p, box, viscosity, modes, static_cast<int>(x0), static_cast<int>(x0 + nx));
  modes.comp_stride = 2 * comp;  // the slab's components, not the whole spectrum's
  c3 = std::pow(2.0 * std::numbers::pi * p.sigma * p.sigma, -1.5);
  dv = p.spacing[0] * p.spacing[1] * p.spacing[2];
  rotation_constants = rpy::pse::detail::rotation_mode_constants(p, viscosity);
}

// The ranks owning the x planes of each particle's window (each rank once, in rank order).
std::vector<std::vector<std::uint32_t>> SlabWaveSpace::Slab::destinations(std::span<const double> x) const {
  std::vector<std::vector<std::uint32_t>> send(static_cast<std::size_t>(comm.size()));
  std::vector<int> ranks;
  for (std::size_t i = 0; 3 * i < x.size(); ++i) {
    const long s = rpy::pse::detail::window_start(x[3 * i], p.spacing[0], P[0]);
    const int first = rpy::pse::detail::wrap_index(s, n[0]);
    ranks.clear();
    for (int a = 0, gx = first; a < P[0]; ++a, gx = gx + 1 == n[0] ? 0 : gx + 1)
      ranks.push_back(plane_owner[static_cast<std::size_t>(gx)]);
    std::sort(ranks.begin(), ranks.end());
    ranks.erase(std::unique(ranks.begin(), ranks.end()), ranks.end());
    for (const int r : ranks) send[static_cast<std::size_t>(r)].push_back(static_cast<std::uint32_t>(i));
  }
  return send;
}

// Window starts and weights of the received particles, as WaveGrid::set_positions computes them.
void SlabWaveSpace::Slab::windows(const std::vector<double>& received) {
  const std::size_t m = received.size() / 3;
  const int pw = P[0] + P[1] + P[2];
  const double inv_2s2 = 1.0 / (2.0 * p.sigma * p.sigma);
  std::array<std::vector<double>, 3> tail;
  for (std::size_t d = 0; d < 3; ++d) tail[d] = rpy::pse::detail::window_tail(p.spacing[d], P[d], inv_2s2);
  start.resize(3 * m);
  weights.resize(static_cast<std::size_t>(pw) * m);
  for (std::size_t k = 0; k < m; ++k) {
    double* w = &weights[static_cast<std::size_t>(pw) * k];
    for (std::size_t d = 0; d < 3; ++d) {
      start[3 * k + d] = rpy::pse::detail::window_weights_recurrence(received[3 * k + d], p.spacing[d], P[d], n[d],
                                                                     inv_2s2, tail[d].data(), w);
      w += P[d];
    }
  }
}

// f_n = sum_j c3 F_j g(x_n - x_j) on this slab's planes ([PSE] eq. 19, D; docs/theory/pse.md), onto
// the three components at `base`; F_j = loads[width j + at ...] (forces, or with rotation torques).
void SlabWaveSpace::Slab::spread(const std::vector<double>& loads, std::size_t width, std::size_t at,
                                 fftw_complex* base) {
  std::fill(component(base, 0), component(base, 0) + 6 * comp, 0.0);
  const int pw = P[0] + P[1] + P[2];
  for (std::size_t k = 0; width * k < loads.size(); ++k) {
    const double* wx = &weights[static_cast<std::size_t>(pw) * k];
    const double* wy = wx + P[0];
    const double* wz = wy + P[1];
    const double* f = &loads[width * k + at];
    const double fc[3] = {c3 * f[0], c3 * f[1], c3 * f[2]};
    for (int a = 0, gx = start[3 * k]; a < P[0]; ++a, gx = gx + 1 == n[0] ? 0 : gx + 1) {
      if (!owns(gx)) continue;
      for (int b = 0, gy = start[3 * k + 1]; b < P[1]; ++b, gy = gy + 1 == n[1] ? 0 : gy + 1) {
        const double wxy = wx[a] * wy[b];
        for (int c = 0; c < 3; ++c) {
          double* line = component(base, c) + real_index(gx, gy, 0);
          for (int l = 0, gz = start[3 * k + 2]; l < P[2]; ++l, gz = gz + 1 == n[2] ? 0 : gz + 1)
            line[gz] += wxy * (wz[l] * fc[c]);
        }
      }
    }
  }
}

// B of [PSE] eq. 19 on the slab's modes (scale_mode_with, the serial operator's per-mode scaling)
// where `deterministic`, plus (or, without it, in place of the spectrum) noise_scale B^{1/2} z2 of
// eq. 21 with a noise key: each mode's z2 is normal6 of its pair's representative under
// (seed, step) (draw_mode_noise, as the serial double grids draw it), a function of the mode
// alone, so the field is the serial one whatever the slabs.
void SlabWaveSpace::Slab::scale(bool deterministic, const rpy::pse::detail::NoiseKey* noise, double noise_scale) {
  auto* spec = reinterpret_cast<double*>(data);
  const double noise_factor = noise_scale / std::sqrt(dv);
  const auto planes = static_cast<std::int64_t>(nx);
#pragma omp parallel for schedule(static)
  for (std::int64_t lx = 0; lx < planes; ++lx)
    for (int iy = 0; iy < n[1]; ++iy)
      for (int iz = 0; iz < nzh; ++iz) {
        const int ix = static_cast<int>(x0 + lx);
        const std::size_t idx =
            (static_cast<std::size_t>(lx) * static_cast<std::size_t>(n[1]) + static_cast<std::size_t>(iy)) *
                static_cast<std::size_t>(nzh) +
            static_cast<std::size_t>(iz);
        double z[6];
        const bool representative =
            noise == nullptr || rpy::pse::detail::draw_mode_noise(ix, iy, iz, modes, noise->seed, noise->step, z);
        rpy::pse::detail::scale_mode_with(ix, iy, iz, idx, modes, ck.data(), spec, deterministic,
                                          noise != nullptr ? z : static_cast<const double*>(nullptr), representative,
                                          noise_factor);
      }
}

// This slab's share of sum_n g(x_n - x_j) u_n for every received particle from the three
// components at `base` ([PSE] eq. 19, D^-1, without its factor c3 dV, which the particle's rank
// applies to the sum of the shares), added to shares[width j + at ...] (zeroed by the caller).
void SlabWaveSpace::Slab::interpolate(const fftw_complex* base, std::vector<double>& shares, std::size_t width,
                                      std::size_t at) const {
  const int pw = P[0] + P[1] + P[2];
  const std::size_t m = start.size() / 3;
  for (std::size_t k = 0; k < m; ++k) {
    const double* wx = &weights[static_cast<std::size_t>(pw) * k];
    const double* wy = wx + P[0];
    const double* wz = wy + P[1];
    for (int a = 0, gx = start[3 * k]; a < P[0]; ++a, gx = gx + 1 == n[0] ? 0 : gx + 1) {
      if (!owns(gx)) continue;
      for (int b = 0, gy = start[3 * k + 1]; b < P[1]; ++b, gy = gy + 1 == n[1] ? 0 : gy + 1) {
        const double wxy = wx[a] * wy[b];
        for (int c = 0; c < 3; ++c) {
          const double* line = component(base, c) + real_index(gx, gy, 0);
          double s = 0.0;
          for (int l = 0, gz = start[3 * k + 2]; l < P[2]; ++l, gz = gz + 1 == n[2] ? 0 : gz + 1) s += wz[l] * line[gz];
          shares[width * k + at + static_cast<std::size_t>(c)] += wxy * s;
        }
      }
    }
  }
}

SlabWaveSpace::SlabWaveSpace(const Communicator& comm, const rpy::pse::PseParameters& p,
                             const std::array<double, 3>& box, double viscosity)
    : slab_(std::make_unique<Slab>(comm, p)) {
  slab_->plan(box, viscosity);
}

SlabWaveSpace::~SlabWaveSpace() = default;

void SlabWaveSpace::set_positions(std::span<const double> x) {
  Slab& s = *slab_;
  s.exchange = IndexExchange{.send = s.destinations(x), .recv_counts = {}, .self = s.comm.rank(), .traffic = {}};
  s.windows(s.exchange.forward(s.comm, x.data(), 3, kWhere, "the positions sent to the grid's slabs"));
}

// The transform back of each of `grids` (three components each), the slabs' interpolation shares
// of all of them to the particles' ranks in one exchange, each particle's shares added in rank
// order of the slabs (a fixed order: repeated products agree bit for bit), then out_g (+)= c3 dV
// sum_g for grid g (every window touches at least one slab).
void SlabWaveSpace::Slab::to_particles(std::span<fftw_complex* const> grids, std::span<double* const> outs,
                                       std::size_t particles, bool accumulate) {
  const std::size_t width = 3 * grids.size();
  std::vector<double> mine(width * (start.size() / 3), 0.0);
  for (std::size_t g = 0; g < grids.size(); ++g) {
    for (int c = 0; c < 3; ++c) fftw_mpi_execute_dft_c2r(backward, spectrum(grids[g], c), component(grids[g], c));
    interpolate(grids[g], mine, width, 3 * g);
  }
  const std::vector<double> shares =
      exchange.backward(comm, mine, width, kWhere, "the velocities sent back from the grid's slabs");
  std::vector<double> sum(width * particles, 0.0);
  std::size_t at = 0;
  for (const auto& list : exchange.send)
    for (const std::uint32_t i : list) {
      for (std::size_t c = 0; c < width; ++c) sum[width * i + c] += shares[at + c];
      at += width;
    }
  const double factor = c3 * dv;
  for (std::size_t g = 0; g < outs.size(); ++g)
    for (std::size_t i = 0; i < particles; ++i)
      for (std::size_t c = 0; c < 3; ++c) {
        double& o = outs[g][3 * i + c];
        const double v = factor * sum[width * i + 3 * g + c];
        o = accumulate ? o + v : v;
      }
}

void SlabWaveSpace::Slab::transform_forward(fftw_complex* base) {
  for (int c = 0; c < 3; ++c) fftw_mpi_execute_dft_r2c(forward, component(base, c), spectrum(base, c));
}

// The torque slabs (the plans run on them by FFTW's new-array execute: the same in-place layout
// and alignment as `data`) and the rotational factors of the slab's modes, once.
void SlabWaveSpace::Slab::allocate_rotation() {
  if (rotation_data != nullptr) return;
  comm.run([&] {
    rotation_data = fftw_alloc_complex(3 * comp);
    require(rotation_data != nullptr, ErrorCode::out_of_memory, kWhere,
            "could not allocate the FFT slabs of the rotational wave space");
  });
  const std::size_t modes_here =
      static_cast<std::size_t>(nx) * static_cast<std::size_t>(n[1]) * static_cast<std::size_t>(nzh);
  rotation_factors.resize(modes_here);
  for (std::size_t idx = 0; idx < modes_here; ++idx) {
    const std::size_t line = idx / static_cast<std::size_t>(nzh);
    const int ix = static_cast<int>(x0 + static_cast<std::ptrdiff_t>(line / static_cast<std::size_t>(n[1])));
    const int iy = static_cast<int>(line % static_cast<std::size_t>(n[1]));
    const int iz = static_cast<int>(idx % static_cast<std::size_t>(nzh));
    rotation_factors[idx] = rpy::pse::detail::rotation_mode_factors(ix, iy, iz, modes, rotation_constants);
  }
}

// [U; W] of every slab mode (scale_rotation_mode, the serial operator's per-mode scaling with
// rotation): from the force and torque spectra where `deterministic`, plus (or, without it, in
// place of them) noise_scale times the wave noise of `noise`, the translational field z2 of each
// mode as scale() draws it (draw_mode_noise), so that U's noise is the translational sampler's.
void SlabWaveSpace::Slab::scale_rotation(bool deterministic, const rpy::pse::detail::NoiseKey* noise,
                                         double noise_scale) {
  auto* fs = reinterpret_cast<double*>(data);
  auto* ts = reinterpret_cast<double*>(rotation_data);
  const double noise_factor = noise_scale / std::sqrt(dv);
  const auto planes = static_cast<std::int64_t>(nx);
#pragma omp parallel for schedule(static)
  for (std::int64_t lx = 0; lx < planes; ++lx)
    for (int iy = 0; iy < n[1]; ++iy)
      for (int iz = 0; iz < nzh; ++iz) {
        const std::size_t idx =
            (static_cast<std::size_t>(lx) * static_cast<std::size_t>(n[1]) + static_cast<std::size_t>(iy)) *
                static_cast<std::size_t>(nzh) +
            static_cast<std::size_t>(iz);
        const int ix = static_cast<int>(x0 + lx);
        double z[6];
        const bool representative =
            noise == nullptr || rpy::pse::detail::draw_mode_noise(ix, iy, iz, modes, noise->seed, noise->step, z);
        rpy::pse::detail::scale_rotation_mode(ix, iy, iz, idx, modes, ck.data(), rotation_factors[idx], fs, ts,
                                              deterministic, noise != nullptr ? z : static_cast<const double*>(nullptr),
                                              representative, noise_factor);
      }
}

void SlabWaveSpace::apply(const double* forces, double* out, std::size_t n, const rpy::pse::detail::NoiseKey* noise,
                          double noise_scale) {
  Slab& s = *slab_;
  s.spread(s.exchange.forward(s.comm, forces, 3, kWhere, "the forces sent to the grid's slabs"), 3, 0, s.data);
  s.transform_forward(s.data);
  s.scale(true, noise_scale != 0.0 ? noise : nullptr, noise_scale);
  fftw_complex* const grids[] = {s.data};
  double* const outs[] = {out};
  s.to_particles(grids, outs, n, false);
}

void SlabWaveSpace::apply_rotation(const double* forces, const double* torques, double* velocities, double* angular,
                                   std::size_t n) {
  Slab& s = *slab_;
  s.allocate_rotation();
  // Forces and torques in one exchange, six values per particle.
  std::vector<double> loads(6 * n);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t c = 0; c < 3; ++c) {
      loads[6 * i + c] = forces[3 * i + c];
      loads[6 * i + 3 + c] = torques[3 * i + c];
    }
  const std::vector<double> received =
      s.exchange.forward(s.comm, loads.data(), 6, kWhere, "the forces and torques sent to the grid's slabs");
  s.spread(received, 6, 0, s.data);
  s.spread(received, 6, 3, s.rotation_data);
  s.transform_forward(s.data);
  s.transform_forward(s.rotation_data);
  s.scale_rotation(true, nullptr, 0.0);
  fftw_complex* const grids[] = {s.data, s.rotation_data};
  double* const outs[] = {velocities, angular};
  s.to_particles(grids, outs, n, false);
}

void SlabWaveSpace::add_noise_rotation(const rpy::pse::detail::NoiseKey& key, double* velocities, double* angular,
                                       std::size_t n) {
  Slab& s = *slab_;
  s.allocate_rotation();
  s.scale_rotation(false, &key, 1.0);
  fftw_complex* const grids[] = {s.data, s.rotation_data};
  double* const outs[] = {velocities, angular};
  s.to_particles(grids, outs, n, true);
}

void SlabWaveSpace::add_noise(const rpy::pse::detail::NoiseKey& key, double* out, std::size_t n) {
  Slab& s = *slab_;
  s.scale(false, &key, 1.0);
  fftw_complex* const grids[] = {s.data};
  double* const outs[] = {out};
  s.to_particles(grids, outs, n, true);
}

std::size_t SlabWaveSpace::sent() const {
  return slab_->exchange.sent();
}
std::size_t SlabWaveSpace::received() const {
  return slab_->exchange.received();
}
IndexExchange::Traffic SlabWaveSpace::traffic() const {
  return slab_->exchange.traffic;
}

}  // namespace rpyfmm::mpi::detail
