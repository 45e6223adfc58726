// rpyfmm CLI — reading the input of `rpyfmm laplace` (laplace_problem.hpp).
#include "laplace_problem.hpp"

#include <cstddef>
#include <string>
#include <vector>

#include "array_io.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/direct.hpp"

namespace rpyfmm::cli {

LaplaceProblem read_laplace_problem(const std::string& sources, const std::string& targets,
                                    const std::string& charges) {
  LaplaceProblem p;
  p.sources = as_points(read_array(sources), "sources");
  p.n = p.sources.size() / 3;
  if (!targets.empty()) p.targets = as_points(read_array(targets), "targets");
  p.m = targets.empty() ? p.n : p.targets.size() / 3;

  const Array q = read_array(charges);
  const auto& s = q.shape;
  if (s.size() == 1 || (s.size() == 2 && s[1] == 1 && s[0] == p.n)) {
    p.charges = as_vector(q, p.n, "charges");
    p.nd = 1;
  } else if (s.size() == 2 && s[1] == p.n && s[0] >= 1) {
    p.nd = s[0];
    p.charges_2d = true;
    require_finite(q.data, "charges", "charges", p.n);
    p.charges = q.data;
  } else {
    std::string shape = "(";
    for (std::size_t i = 0; i < s.size(); ++i) {
      if (i > 0) shape += ',';
      shape += std::to_string(s[i]);
    }
    fail(ErrorCode::invalid_input, "charges",
         "must have shape (" + std::to_string(p.n) + ",) or (nd," + std::to_string(p.n) + ") to match " +
             std::to_string(p.n) + " sources, got " + shape + ")");
  }
  return p;
}

std::vector<std::size_t> laplace_output_shape(const LaplaceProblem& p) {
  std::vector<std::size_t> shape = {p.m, fmm::result_width};
  if (p.charges_2d) shape.insert(shape.begin(), p.nd);
  return shape;
}

}  // namespace rpyfmm::cli
