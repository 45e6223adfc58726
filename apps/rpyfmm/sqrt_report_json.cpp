// rpyfmm CLI — the sampler's report in a --json line (sqrt_report_json.hpp).
#include "sqrt_report_json.hpp"

namespace rpyfmm::cli {

void add_sqrt_report(JsonLine& line, const rpy::SqrtReport& report) {
  line.add("iterations", report.iterations)
      .add("error_estimate", report.error_estimate)
      .add("operator_applications", report.operator_applications)
      .add("converged", report.converged)
      .add("breakdown", report.breakdown)
      .add("preconditioner_blocks", report.preconditioner_blocks);
}

void add_chebyshev_bounds(JsonLine& line, const rpy::SqrtReport& report) {
  if (report.method == rpy::SqrtMethod::chebyshev) {
    line.add("lambda_min", report.lambda_min).add("lambda_max", report.lambda_max);
  }
}

}  // namespace rpyfmm::cli
