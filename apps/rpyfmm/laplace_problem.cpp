// rpyfmm CLI — reading the input of `rpyfmm laplace` (laplace_problem.hpp).
#include "laplace_problem.hpp"

#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

#include "array_io.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/direct.hpp"

namespace rpyfmm::cli {

ChargesLayout charges_layout(const std::vector<std::size_t>& s, std::size_t n) {
  if (s.size() == 1 || (s.size() == 2 && s[1] == 1 && s[0] == n)) {
    require_vector_shape(s, n, "charges");
    return {1, false};
  }
  if (s.size() == 2 && s[1] == n && s[0] >= 1) return {s[0], true};
  fail(ErrorCode::invalid_input, "charges",
       "must have shape (" + std::to_string(n) + ",) or (nd," + std::to_string(n) + ") to match " + std::to_string(n) +
           " sources, got " + shape_text(s));
}

Error nonfinite_charge(std::size_t index, bool nan, const ChargesLayout& layout, std::size_t n) {
  // as_vector's words for one density, require_finite's (where: what) for (nd, n).
  if (!layout.two_d) return Error(ErrorCode::invalid_input, "charges " + nonfinite_entry(index, 1, nan));
  return Error(ErrorCode::invalid_input, "charges: charges " + nonfinite_entry(index, n, nan));
}

LaplaceProblem read_laplace_problem(const std::string& sources, const std::string& targets,
                                    const std::string& charges) {
  LaplaceProblem p;
  p.sources = as_points(read_array(sources), "sources");
  p.n = p.sources.size() / 3;
  if (!targets.empty()) p.targets = as_points(read_array(targets), "targets");
  p.m = targets.empty() ? p.n : p.targets.size() / 3;

  const Array q = read_array(charges);
  const ChargesLayout layout = charges_layout(q.shape, p.n);
  p.nd = layout.nd;
  p.charges_2d = layout.two_d;
  if (const auto i = first_nonfinite(q.data)) throw nonfinite_charge(*i, std::isnan(q.data[*i]), layout, p.n);
  p.charges = q.data;
  return p;
}

std::vector<std::size_t> laplace_output_shape(const LaplaceProblem& p) {
  std::vector<std::size_t> shape = {p.m, fmm::result_width};
  if (p.charges_2d) shape.insert(shape.begin(), p.nd);
  return shape;
}

}  // namespace rpyfmm::cli
