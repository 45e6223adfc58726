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
/// The inner product <a, b> of two vectors of length n. Empty: the sequential sum over the n
/// entries. A hook sums over vectors distributed across MPI ranks (mpi::DistributedRigidBodies):
/// each rank passes its own entries, the hook returns the global sum, the same on every rank.
using InnerProduct = std::function<double(const double* a, const double* b, std::size_t n)>;

/// sum_i a_i b_i in increasing i: the same result for any thread count (GMRES's inner product
/// without a hook).
double sequential_dot(const double* a, const double* b, std::size_t n);

struct GmresResult {
  int iterations = 0;      ///< products with A
  int restarts = 0;        ///< restarts performed
  bool converged = false;  ///< ||b - A x|| <= tol ||b|| (GMRES's recurrence estimate)
  double residual = 0.0;   ///< that estimate, relative to ||b||
};

/// Solves A x = b from the initial guess in x, right-preconditioned (A P^{-1} u = b, x = P^{-1} u;
/// `precondition` empty = none), restarting every `restart` iterations, at most
/// `max_iterations` products in all. `inner_product` empty: the sequential sums. Every decision
/// (stopping, restarting, breakdown) follows from the inner products alone, so with a hook that
/// returns the same value on every rank all ranks take the same steps and the same operator calls.
/// Whether the guess is zero (no first product A x) is decided by every entry being 0 without a
/// hook, and by <x, x> = 0 with one (the same on every rank).
GmresResult gmres(std::size_t n, const VectorMap& apply, const VectorMap& precondition, const double* b, double* x,
                  double tol, int max_iterations, int restart, const InnerProduct& inner_product = {});

}  // namespace rpyfmm::rpy::rigid_detail
