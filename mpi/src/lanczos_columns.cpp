// rpyfmm — the Lanczos square root of several right-hand sides across ranks (lanczos_columns.hpp).
#include "lanczos_columns.hpp"

#include <algorithm>
#include <memory>
#include <vector>

#include "krylov_space.hpp"
#include "sqrt/detail.hpp"
#include "sqrt/krylov.hpp"

namespace rpyfmm::mpi::detail {
namespace {

using rpy::sqrt_detail::LanczosProcess;
using rpy::sqrt_detail::LanczosRhs;

constexpr const char* kWhere = "sqrt_apply(lanczos)";

// The columns: each one's distributed basis and Lanczos state.
struct Columns {
  std::vector<std::unique_ptr<DistributedKrylovSpace>> spaces;
  std::vector<LanczosRhs> state;
};

// The inner products that `need` asks of column c, against its y, appended to xs / ys.
void add_pairs(Columns& cols, std::size_t c, const LanczosProcess::Need& need, const double* y,
               std::vector<const double*>& xs, std::vector<const double*>& ys) {
  DistributedKrylovSpace& space = *cols.spaces[c];
  switch (need.kind) {
    case LanczosProcess::Need::basis:
      for (std::size_t q = 0; q < need.k; ++q) xs.push_back(space.vector(q)), ys.push_back(y);
      break;
    case LanczosProcess::Need::current:
      xs.push_back(space.vector(static_cast<std::size_t>(cols.state[c].process.size()))), ys.push_back(y);
      break;
    case LanczosProcess::Need::self:
      xs.push_back(y), ys.push_back(y);
      break;
    case LanczosProcess::Need::none:
      break;
  }
}

// The Lanczos step of every column of `active` on its product (y, n entries each, in the order
// of `active`), to its end: each stage's inner products of all the columns in one exchange.
void step_columns(Columns& cols, const std::vector<std::size_t>& active, double* y, std::size_t n) {
  std::vector<LanczosProcess::Need> needs(active.size());
  for (std::size_t a = 0; a < active.size(); ++a) needs[a] = cols.state[active[a]].process.begin_step(y + a * n);
  std::vector<const double*> xs, ys;
  std::vector<double> values;
  for (;;) {
    xs.clear();
    ys.clear();
    for (std::size_t a = 0; a < active.size(); ++a) add_pairs(cols, active[a], needs[a], y + a * n, xs, ys);
    if (xs.empty()) return;
    values.resize(xs.size());
    cols.spaces.front()->pair_dots(xs.size(), xs.data(), ys.data(), values.data());
    std::size_t first = 0;
    for (std::size_t a = 0; a < active.size(); ++a) {
      if (needs[a].kind == LanczosProcess::Need::none) continue;
      const std::size_t count = needs[a].kind == LanczosProcess::Need::basis ? needs[a].k : 1;
      needs[a] = cols.state[active[a]].process.continue_step(values.data() + first, kWhere, active[a]);
      first += count;
    }
  }
}

// Starts every column from its z (their norms in one exchange); a zero z gives w = 0 at once.
void start_columns(Columns& cols, std::size_t n, const double* z, double* w) {
  const std::size_t nrhs = cols.state.size();
  std::vector<const double*> zs(nrhs);
  for (std::size_t c = 0; c < nrhs; ++c) zs[c] = z + c * n;
  std::vector<double> zz(nrhs);
  cols.spaces.front()->pair_dots(nrhs, zs.data(), zs.data(), zz.data());
  for (std::size_t c = 0; c < nrhs; ++c) {
    LanczosRhs& s = cols.state[c];
    s.znorm = s.process.start(zs[c], zz[c]);
    if (s.znorm == 0.0) {  // M^{1/2} 0 = 0 exactly
      cols.spaces[c]->combine(0, nullptr, w + c * n);
      s.active = false;
    }
  }
}

// The columns still iterating, in column order.
std::vector<std::size_t> active_columns(const Columns& cols) {
  std::vector<std::size_t> active;
  for (std::size_t c = 0; c < cols.state.size(); ++c)
    if (cols.state[c].active) active.push_back(c);
  return active;
}

// y = A v for the current basis vector v of every column of `active` (n entries each, in that
// order), in one product call, counted in the report and checked finite on every rank.
void multiply(const Communicator& comm, const ColumnsProduct& product, const Columns& cols,
              const std::vector<std::size_t>& active, std::size_t n, std::vector<double>& y, rpy::SqrtReport& report) {
  std::vector<double> x(active.size() * n);
  y.resize(active.size() * n);
  for (std::size_t a = 0; a < active.size(); ++a)
    std::copy_n(cols.state[active[a]].process.current(), n, x.data() + a * n);
  product(x.data(), y.data(), active.size());
  ++report.operator_applications;
  report.vector_products += static_cast<long long>(active.size());
  comm.run([&] {
    rpy::sqrt_detail::require_finite_product(y.data(), n, active.size(), kWhere, report.operator_applications);
  });
}

// The report's largest change and any breakdown over the columns, and the inner products' cost.
void summarize(const Columns& cols, rpy::SqrtReport& report, InnerProductStats* stats) {
  for (const LanczosRhs& s : cols.state) {
    report.error_estimate = std::max(report.error_estimate, s.change);
    report.breakdown = report.breakdown || s.breakdown;
  }
  if (stats == nullptr) return;
  *stats = {};
  for (const auto& space : cols.spaces) {
    stats->seconds += space->communication_seconds();
    stats->exchanges += space->exchanges();
  }
}

}  // namespace

rpy::SqrtReport lanczos_columns(const Communicator& comm, std::span<const std::size_t> counts, std::size_t segments,
                                const ColumnsProduct& product, std::size_t nrhs, const double* z, double* w,
                                const rpy::SqrtOptions& options, InnerProductStats* stats) {
  rpy::SqrtReport report;
  report.method = rpy::SqrtMethod::lanczos;
  Columns cols;
  for (std::size_t c = 0; c < nrhs; ++c) {
    cols.spaces.push_back(std::make_unique<DistributedKrylovSpace>(comm, counts, segments));
    cols.state.push_back(
        LanczosRhs{LanczosProcess(*cols.spaces[c], options.reorthogonalize), 0.0, {}, 0.0, true, false});
  }
  const std::size_t n = 3 * segments * counts[static_cast<std::size_t>(comm.rank())];
  const int max_it = rpy::sqrt_detail::lanczos_max_iterations(options, cols.spaces.front()->n());
  start_columns(cols, n, z, w);
  std::vector<double> y;
  for (int it = 0; it < max_it; ++it) {
    const std::vector<std::size_t> active = active_columns(cols);
    if (active.empty()) break;
    multiply(comm, product, cols, active, n, y, report);
    step_columns(cols, active, y.data(), n);
    for (std::size_t a = 0; a < active.size(); ++a) {
      const std::size_t c = active[a];
      rpy::sqrt_detail::conclude_lanczos_step(cols.state[c], cols.state[c].process.broke_down(), it, max_it, options, c,
                                              w + c * n, report);
    }
  }
  summarize(cols, report, stats);
  return report;
}

}  // namespace rpyfmm::mpi::detail
