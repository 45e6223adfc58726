// rpyfmm Python bindings — the Laplace kernel 1/r: FMM plan and direct sums
// (fmm/include/rpyfmm/fmm/laplace_fmm.hpp, direct.hpp).
//
// Results per target: [pot, gx, gy, gz, hxx, hyy, hzz, hxy, hxz, hyz] of
// phi(x) = sum_j q_j / |x - y_j| (no 1/(4 pi)); shape (M, 10), or (nd, M, 10)
// for charges of shape (nd, N).
#include <nanobind/stl/map.h>
#include <nanobind/stl/string.h>

#include "common.hpp"
#include "object_lock.hpp"
#include "rpyfmm/core/ranges.hpp"
#include "rpyfmm/fmm/direct.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/fmm/leaf_grid.hpp"

namespace rpyfmm::python {

unsigned outputs_from(nb::handle outputs, const std::string& where) {
  unsigned mask = 0;
  if (nb::try_cast(outputs, mask, false)) return mask;  // validated by the library
  auto one = [&](const std::string& name) -> unsigned {
    if (name == "potential") return fmm::potential;
    if (name == "gradient") return fmm::gradient;
    if (name == "hessian") return fmm::hessian;
    if (name == "all") return fmm::all_outputs;
    fail(ErrorCode::invalid_argument, where,
         "unknown output '" + name + "' (expected potential, gradient, hessian or all)");
  };
  std::string text;
  if (nb::try_cast(outputs, text, false)) {
    std::size_t start = 0;
    while (start <= text.size()) {
      const std::size_t bar = text.find('|', start);
      mask |= one(text.substr(start, bar == std::string::npos ? std::string::npos : bar - start));
      if (bar == std::string::npos) break;
      start = bar + 1;
    }
    return mask;
  }
  const char* expected = "outputs must be an int mask, a name or a sequence of names";
  if (!nb::isinstance<nb::sequence>(outputs)) fail(ErrorCode::invalid_argument, where, expected);
  for (nb::handle item : nb::borrow<nb::sequence>(outputs)) {
    std::string name;
    if (!nb::try_cast(item, name, false)) fail(ErrorCode::invalid_argument, where, expected);
    mask |= one(name);
  }
  return mask;
}

std::size_t densities(const InArray& q, const std::string& where) {
  if (q.ndim() == 1) return 1;
  if (q.ndim() == 2) return q.shape[0];
  fail(ErrorCode::invalid_input, where, "charges has shape " + shape_string(q.shape) + ", expected (N,) or (nd, N)");
}

std::vector<std::size_t> result_shape(const InArray& q, std::size_t m) {
  if (q.ndim() == 1) return {m, fmm::result_width};
  return {q.shape[0], m, fmm::result_width};
}

nb::dict tree_stats_dict(const fmm::TreeStats& s) {
  nb::dict d;
  d["levels"] = s.levels;
  d["boxes"] = s.boxes;
  d["leaves"] = s.leaves;
  d["memory_bytes"] = s.memory_bytes;
  d["order"] = s.order;
  d["nlams"] = s.nlams;
  d["leaf_capacity"] = s.leaf_capacity;
  d["root_scale"] = s.root_scale;
  d["u_pairs"] = s.u_pairs;
  d["w_pairs"] = s.w_pairs;
  d["x_pairs"] = s.x_pairs;
  d["leaf_level_share"] = s.leaf_level_share;
  return d;
}

namespace {

void bind_output_constants(nb::module_& m) {
  m.attr("POTENTIAL") = static_cast<unsigned>(fmm::potential);
  m.attr("GRADIENT") = static_cast<unsigned>(fmm::gradient);
  m.attr("HESSIAN") = static_cast<unsigned>(fmm::hessian);
  m.attr("ALL_OUTPUTS") = fmm::all_outputs;
  m.attr("RESULT_COLUMNS") = nb::make_tuple("pot", "gx", "gy", "gz", "hxx", "hyy", "hzz", "hxy", "hxz", "hyz");
}

// Explicit targets: None means "at the sources"; an empty array is refused, since the library reads
// an empty target span as "at the sources" and would silently return N rows instead of none.
InArray targets_from(OptArrayArg targets, const std::string& where) {
  InArray t;
  if (targets.is_none()) return t;
  t = as_input(targets, where, "targets");
  require(require_points(t, where, "targets") > 0, ErrorCode::invalid_input, where,
          "targets is empty (0 points); pass targets=None to evaluate at the sources");
  return t;
}

void set_points(fmm::LaplaceFmm& self, ArrayArg sources, OptArrayArg targets) {
  const InArray s = as_input(sources, "LaplaceFmm.set_points", "sources");
  require_points(s, "LaplaceFmm.set_points", "sources");
  const InArray t = targets_from(targets, "LaplaceFmm.set_points");
  nb::gil_scoped_release release;
  self.set_points(s.span(), t.span());
}

ArrayResult evaluate(const fmm::LaplaceFmm& self, ArrayArg charges, nb::handle outputs, OutArg out) {
  const std::string where = "LaplaceFmm.evaluate";
  const unsigned mask = outputs_from(outputs, where);
  const InArray q = as_input(charges, where, "charges");
  const std::size_t nd = densities(q, where);
  require(self.num_sources() > 0, ErrorCode::invalid_input, where, "call set_points first");
  OutArray r = make_output(out, result_shape(q, self.num_targets()), where, &q);
  {
    nb::gil_scoped_release release;
    self.evaluate(q.span(), nd, mask, r.span());
  }
  return ArrayResult{r.object};
}

ArrayResult laplace_direct(ArrayArg sources, ArrayArg charges, OptArrayArg targets, nb::handle outputs, OutArg out) {
  const std::string where = "laplace_direct";
  const unsigned mask = outputs_from(outputs, where);
  const InArray s = as_input(sources, where, "sources");
  const std::size_t n = require_points(s, where, "sources");
  const InArray t = targets_from(targets, where);
  const std::size_t mt = targets.is_none() ? n : t.size / 3;
  const InArray q = as_input(charges, where, "charges");
  const std::size_t nd = densities(q, where);
  OutArray r = make_output(out, result_shape(q, mt), where, &q);
  {
    nb::gil_scoped_release release;
    fmm::laplace_direct(s.span(), q.span(), nd, t.span(), mask, r.span());
  }
  return ArrayResult{r.object};
}

void bind_laplace_fmm(nb::module_& m) {
  nb::class_<fmm::LaplaceFmm>(
      m, "LaplaceFmm",
      "Adaptive plane-wave FMM for phi(x) = sum_j q_j / |x - y_j| (no 1/(4 pi)).\n\n"
      "Plan once (set_points), evaluate many charge vectors. Lengths in any unit;\n"
      "potential in charge/length, gradient charge/length^2, Hessian charge/length^3.\n"
      "l2 error of each output <= tolerance times that of the charges' absolute field sum |q_j| / r^(k+1)\n"
      "(the relative error where the field does not cancel; docs/theory/fmm.md, Sec. 7).")
      .def(
          "__init__",
          [](fmm::LaplaceFmm* self, std::optional<double> tolerance, int leaf_capacity, int order, double root_scale,
             std::optional<double> eps) {
            fmm::FmmOptions o;
            o.tolerance = renamed_keyword(tolerance, eps, o.tolerance, "LaplaceFmm", "tolerance", "eps");
            o.leaf_capacity = leaf_capacity;
            o.order = order;
            o.root_scale = root_scale;
            new (self) fmm::LaplaceFmm(o);
          },
          nb::arg("tolerance").sig("1e-06") = nb::none(), nb::arg("leaf_capacity") = 0, nb::arg("order") = 0,
          nb::arg("root_scale") = 1.0, nb::kw_only(), nb::arg("eps") = nb::none(),
          "tolerance: requested accuracy in [1e-15, 1e-1] (see the class); leaf_capacity: points per leaf\n"
          "(0 = automatic); order: expansion order (0 = from tolerance); root_scale: root box side over the\n"
          "points' bounding cube, in [1, 8] (1 = the bounding cube; above 1 anchored at the low corner, see\n"
          "fit_leaf_grid). eps: deprecated spelling of tolerance (DeprecationWarning).")
      .def("set_points", locked("LaplaceFmm.set_points", &set_points), nb::arg("sources"),
           nb::arg("targets") = nb::none(),
           "Builds the tree and lists. sources: (N, 3) or (3N,) positions; targets: (M, 3) or None to evaluate\n"
           "at the sources (self pair excluded). The points are copied into the plan.")
      .def("evaluate", locked("LaplaceFmm.evaluate", &evaluate), nb::arg("charges"), nb::arg("outputs") = "all",
           nb::arg("out") = nb::none(),
           "Potential/gradient/Hessian at the targets. charges: (N,) or (nd, N); outputs: 'all', a name\n"
           "('potential', 'gradient', 'hessian'), 'potential|gradient', a list of names or an int mask.\n"
           "Returns (M, 10) or (nd, M, 10) float64 [pot, gx, gy, gz, hxx, hyy, hzz, hxy, hxz, hyz]\n"
           "(unrequested columns are 0); `out` is written in place and returned.")
      .def_prop_ro(
          "tolerance", [](const fmm::LaplaceFmm& self) { return self.options().tolerance; },
          "Requested accuracy (see the class).")
      .def_prop_ro(
          "eps",
          [](const fmm::LaplaceFmm& self) {
            warn_deprecated("LaplaceFmm.eps is deprecated; use LaplaceFmm.tolerance");
            return self.options().tolerance;
          },
          "Deprecated spelling of tolerance (DeprecationWarning).")
      .def_prop_ro("num_sources",
                   locked_read(
                       "LaplaceFmm.num_sources", +[](const fmm::LaplaceFmm& self) { return self.num_sources(); }),
                   "Number of source points N (0 before set_points).")
      .def_prop_ro("num_targets",
                   locked_read(
                       "LaplaceFmm.num_targets", +[](const fmm::LaplaceFmm& self) { return self.num_targets(); }),
                   "Number of target points M (N when evaluating at the sources).")
      .def("stats",
           locked_read(
               "LaplaceFmm.stats", +[](const fmm::LaplaceFmm& self) { return tree_stats_dict(self.stats()); }),
           "Tree shape and plan memory: levels, boxes, leaves, memory_bytes, order, nlams, ...")
      .def("last_timings",
           locked_read(
               "LaplaceFmm.last_timings", +[](const fmm::LaplaceFmm& self) { return self.last_timings(); }),
           "Stage times in seconds of set_points and of the last evaluate.");
}

void bind_laplace_functions(nb::module_& m) {
  m.def("laplace_direct", &laplace_direct, nb::arg("sources"), nb::arg("charges"), nb::arg("targets") = nb::none(),
        nb::arg("outputs") = "all", nb::arg("out") = nb::none(),
        "Exact O(N M) sums of 1/r (self pair skipped); same arguments and result layout as LaplaceFmm.evaluate.");

  m.def(
      "fmm_default_leaf_capacity",
      [](std::optional<double> tolerance, std::optional<double> eps) {
        const double t = renamed_keyword(tolerance, eps, fmm::FmmOptions{}.tolerance, "fmm_default_leaf_capacity",
                                         "tolerance", "eps");
        // LaplaceFmm's range: the capacity tables end there, and NaN or a negative value would
        // otherwise pick a table silently.
        ranges::require_in(ranges::kLaplaceTolerance, t, "fmm_default_leaf_capacity", "tolerance");
        return fmm::fmm_default_leaf_capacity(t);
      },
      nb::arg("tolerance").sig("1e-06") = nb::none(), nb::kw_only(), nb::arg("eps") = nb::none(),
      "Capacity (points per leaf before a split) the automatic leaves start from at this tolerance,\n"
      "chosen per plane-wave table and P2P kernel by benchmark. eps: deprecated spelling of tolerance.");

  m.def(
      "fit_leaf_grid",
      [](ArrayArg points, int occupancy, double min_fill) -> nb::object {
        const std::string where = "fit_leaf_grid";
        const InArray x = as_input(points, where, "points");
        require_points(x, where, "points");
        const fmm::LeafGrid grid = fmm::fit_leaf_grid(x.span(), {}, occupancy, min_fill);
        if (!grid.fitted()) return nb::none();
        return nb::make_tuple(grid.leaf_capacity, grid.root_scale);
      },
      nb::arg("points"), nb::arg("occupancy"), nb::arg("min_fill") = 0.0,
      "(leaf_capacity, root_scale) for LaplaceFmm whose leaves hold about `occupancy` of these points\n"
      "(the root box enlarged so that whole leaves span the cloud), or None where the points fill less\n"
      "than min_fill of their bounding cube or fewer than two leaves per side would result.");
}

}  // namespace

void bind_fmm(nb::module_& m) {
  bind_output_constants(m);
  bind_laplace_fmm(m);
  bind_laplace_functions(m);
}

}  // namespace rpyfmm::python
