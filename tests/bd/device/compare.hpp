// Comparisons of the BD device stages with the CPU engine: rows, and arrays either bit for bit or
// within a bound (docs/gpu-bd.md, bounds); the message of a refusal; a step refused by the guard.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/bd/device/device_engine.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/neighbour_list.hpp"
#include "rpyfmm/core/error.hpp"

namespace device_test {

/// True where the compiler may fuse a * b + c (an FMA target): the CPU engine's sources then round
/// differently from the stages (compiled with -ffp-contract=off), and results agree to a bound
/// instead of bit for bit. The project's presets build for x86-64 without FMA (all but `native`).
inline constexpr bool kMayContract =
#if defined(__FMA__) || defined(__aarch64__)
    true;
#else
    false;
#endif

/// Every row of `rows` equals the CPU list's (both sorted: equal as sets).
inline void expect_same_rows(const rpyfmm::bd::device::NeighbourRows& rows, const rpyfmm::bd::NeighbourList& cpu,
                             const char* what) {
  ASSERT_EQ(rows.offsets.size(), cpu.size() + 1) << what;
  std::size_t different = 0;
  for (std::size_t i = 0; i < cpu.size(); ++i) {
    const auto a = rows.row(i);
    const auto b = cpu.neighbours(i);
    if (!std::equal(a.begin(), a.end(), b.begin(), b.end())) {
      if (different++ < 3)
        ADD_FAILURE() << what << ": row " << i << " has " << a.size() << " entries, CPU " << b.size();
    }
  }
  EXPECT_EQ(different, 0u) << what;
  EXPECT_EQ(rows.indices.size(), cpu.pair_entries()) << what;
}

/// |a_k - b_k| <= bound_k for every k, or a == b bit for bit when `bitwise`.
inline void expect_close(std::span<const double> a, std::span<const double> b, std::span<const double> bound,
                         bool bitwise, const char* what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  std::size_t bad = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    const bool ok = bitwise ? a[k] == b[k] : std::abs(a[k] - b[k]) <= bound[k];
    if (!ok && bad++ < 3)
      ADD_FAILURE() << what << ": entry " << k << ": " << a[k] << " vs " << b[k] << " (difference " << a[k] - b[k]
                    << ", bound " << (bitwise ? 0.0 : bound[k]) << ")";
  }
  EXPECT_EQ(bad, 0u) << what;
}

/// A copy of an engine's array (compared with ==).
inline std::vector<double> copy(std::span<const double> v) {
  return {v.begin(), v.end()};
}

/// The not_supported refusal's message of make(), or "" when it is accepted.
template <class Make>
std::string refusal(Make&& make) {
  try {
    (void)make();
  } catch (const rpyfmm::Error& e) {
    EXPECT_EQ(e.code(), rpyfmm::ErrorCode::not_supported) << e.what();
    return e.what();
  }
  return "";
}

/// The first step of `dev` refused by the blow-up guard (numerical_failure), the engine left at
/// step 0 with the positions x, as on the CPU.
inline void expect_blow_up_keeps_the_start(rpyfmm::bd::Integrator& dev, const std::vector<double>& x) {
  try {
    dev.step();
    ADD_FAILURE() << "no blow-up";
  } catch (const rpyfmm::Error& e) {
    EXPECT_EQ(e.code(), rpyfmm::ErrorCode::numerical_failure) << e.what();
  }
  EXPECT_EQ(dev.step_count(), 0u);
  EXPECT_EQ(dev.totals().steps, 0u);
  EXPECT_EQ(copy(dev.positions()), x);
}

}  // namespace device_test
