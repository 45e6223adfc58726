// rpyfmm — PSE wave-space part on the CPU: Spectral Ewald with a Gaussian
// window (Lindbo & Tornberg 2010/2011), FFTW r2c/c2r with threads, race-free
// OpenMP spreading by tile colouring (PSE.md Sec. 2.3, 4, 6.2). Private.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "kernels_common.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"

namespace rpyfmm::rpy::pse::detail {

/// Key of the wave-space noise z2: Philox (seed, step), stream kStreamWave (kernels_common.hpp).
struct NoiseKey {
  std::uint64_t seed = 0;
  std::uint64_t step = 0;
};

/// c(k) = sinc^2(ka) (1 + k^2/4xi^2) exp(-(1-eta) k^2/4xi^2) / (k^2 mu Ng) on the half
/// spectrum, zero at k = 0 and on Nyquist planes (PSE.md Sec. 2.3). Shared with CUDA.
std::vector<double> wave_scaling_table(const PseParameters& p, const std::array<double, 3>& box, double viscosity,
                                       ModeGeometry& geometry);

class WaveSpace {
 public:
  /// fft_measure: FFTW_MEASURE plans instead of FFTW_ESTIMATE (PseOptions::fft_measure).
  WaveSpace(const PseParameters& p, const std::array<double, 3>& box, double viscosity, int fft_threads,
            bool fft_measure);
  ~WaveSpace();
  WaveSpace(const WaveSpace&) = delete;
  WaveSpace& operator=(const WaveSpace&) = delete;

  /// Window starts and weights, tile sort (positions already wrapped into the box).
  void set_positions(std::span<const double> x);

  /// out (+)= M_w forces + noise_scale M_w^{1/2} z2(key). `forces` may be null
  /// (noise only, the forward FFT is skipped); `noise` may be null (deterministic).
  void apply(const double* forces, double* out, bool accumulate, const NoiseKey* noise, double noise_scale,
             StageTimes* times);

 private:
  void spread(const double* forces);
  void interpolate(double* out, bool accumulate) const;
  void window_lines(std::size_t i, std::size_t* xline, std::size_t* yline) const;

  PseParameters p_;
  std::array<int, 3> n_{};
  std::array<int, 3> P_{};
  std::size_t ng_ = 0;
  ModeGeometry modes_{};
  double dv_ = 0.0;
  double c3_ = 0.0;
  std::vector<double> ck_;
  double* grid_ = nullptr;      // 3 x Ng real (fftw_malloc)
  double* spectrum_ = nullptr;  // 3 x modes complex (fftw_malloc)
  void* plan_forward_ = nullptr;
  void* plan_backward_ = nullptr;
  int fft_threads_ = 1;
  bool parallel_modes_ = false;

  // Per particle: wrapped window starts and cached 1D weights (Px + Py + Pz).
  std::size_t np_ = 0;
  std::vector<int> start_;
  std::vector<double> weights_;
  // Tiles for race-free spreading: particles sorted by tile; tiles grouped by colour.
  std::vector<std::size_t> order_;
  std::vector<std::size_t> tile_begin_;              // per tile: range in order_
  std::array<std::vector<int>, 9> tiles_of_colour_;  // tile ids per colour
};

}  // namespace rpyfmm::rpy::pse::detail
