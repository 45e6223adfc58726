// The accuracy of the Laplace FMM under FmmRpy's far field for a requested RPY tolerance
// (docs/theory/rpy.md, Sec. 2, "Tolerance"): the tolerance itself, and within a factor 10 above each
// plane-wave table's step (1e-3, 1e-6, 1e-9, 1e-12) more quadrature nodes and a higher order than
// that table's, because there the table's own error, amplified by the far field's cancellation,
// reaches the RPY tolerance on force dipoles. Shared by rpy::FmmRpy and each owner's serial FMM in
// mpi::DistributedFmmRpy.
#pragma once

namespace rpyfmm::rpy::detail {

/// FmmOptions' tolerance, order and planewave_nodes (0: the tolerance's own) for an RPY tolerance.
struct LaplaceAccuracy {
  double tolerance = 0.0;
  int order = 0;
  int planewave_nodes = 0;
};

[[nodiscard]] LaplaceAccuracy laplace_accuracy_for(double rpy_tolerance);

}  // namespace rpyfmm::rpy::detail
