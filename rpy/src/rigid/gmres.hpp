// rpyfmm — restarted GMRES with right preconditioning (Saad & Schultz 1986; Saad, Iterative
// Methods for Sparse Linear Systems, 2nd ed., Alg. 9.5), matrix-free, for the rigid-body
// saddle-point system (rigid_bodies.cpp). Internal header.
//
// Hand-written rather than Eigen's unsupported GMRES: ours runs on raw operator callbacks (no
// Eigen expression wrappers around a MobilityOperator), sums its inner products in a fixed
// order (results do not depend on the thread count) and reports restarts and the residual.
#pragma once

#include <cstddef>
#include <functional>

namespace rpyfmm::rpy::rigid_detail {

/// y = A x or y = P^{-1} x for vectors of length n.
using VectorMap = std::function<void(const double* x, double* y)>;

struct GmresResult {
  int iterations = 0;      ///< products with A
  int restarts = 0;        ///< restarts performed
  bool converged = false;  ///< ||b - A x|| <= tol ||b|| (GMRES's recurrence estimate)
  double residual = 0.0;   ///< that estimate, relative to ||b||
};

/// Solves A x = b from the initial guess in x, right-preconditioned (A P^{-1} u = b, x = P^{-1} u;
/// `precondition` empty = none), restarting every `restart` iterations, at most
/// `max_iterations` products in all.
GmresResult gmres(std::size_t n, const VectorMap& apply, const VectorMap& precondition, const double* b, double* x,
                  double tol, int max_iterations, int restart);

}  // namespace rpyfmm::rpy::rigid_detail
