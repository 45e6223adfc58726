// True relative error of the Lanczos and Chebyshev square roots versus the
// requested tolerance and the reported error estimate, against the dense
// principal root (Eigen::SelfAdjointEigenSolver) of an RPY matrix (random
// suspension, phi = 0.1, mixed radii in [0.5, 2], overlaps). Documents the
// tolerance semantics (sqrt.hpp). Rows `lanczos+block64` and `chebyshev+block64`: the
// block-preconditioned samplers against their own dense reference B z, B = G^{-1} (G M G^T)^{1/2}
// (rpyfmm/rpy/block_preconditioner.hpp). Prints CSV.
//
// usage: sqrt_accuracy [N=400] [samples=5]
#include <cstdio>
#include <string>

#include "rpyfmm/rpy/block_preconditioner.hpp"
#include "sqrt_test_util.hpp"

using namespace rpyfmm::rpy;

int main(int argc, char** argv) {
  const std::size_t N = argc > 1 ? std::stoul(argv[1]) : 400;
  const int samples = argc > 2 ? std::stoi(argv[2]) : 5;
  const auto x = sqrt_test::random_points(N, 0.1, 5u);
  const auto a = sqrt_test::radii(N, true, 6u);
  const Eigen::MatrixXd M = sqrt_test::rpy_matrix(x, a);
  const Eigen::MatrixXd S = sqrt_test::principal_sqrt(M);
  const auto op = sqrt_test::view_of(M);
  const BlockPreconditioner preconditioner(x, a, 1.0, Geometry::open(), 64);
  Eigen::MatrixXd G(M.rows(), M.cols());  // G column by column
  for (Eigen::Index k = 0; k < M.rows(); ++k) {
    Eigen::VectorXd e = Eigen::VectorXd::Unit(M.rows(), k);
    preconditioner.apply_g(e.data());
    G.col(k) = e;
  }
  const Eigen::MatrixXd B = G.partialPivLu().solve(sqrt_test::principal_sqrt(G * M * G.transpose()));
  std::printf("N,method,tol,iterations,error_estimate,true_error_max,true_error_over_tol\n");
  for (int variant = 0; variant < 4; ++variant) {
    const SqrtMethod m = variant % 2 == 1 ? SqrtMethod::chebyshev : SqrtMethod::lanczos;
    const bool block = variant >= 2;
    for (double tol : {1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8}) {
      double worst = 0, est = 0;
      int its = 0;
      for (int s = 0; s < samples; ++s) {
        const Eigen::VectorXd z = sqrt_test::gaussian(M.rows(), 100u + static_cast<std::uint32_t>(s));
        Eigen::VectorXd w(M.rows());
        SqrtOptions opt;
        opt.method = m;
        opt.tolerance = tol;
        const std::span<const double> zs{z.data(), static_cast<std::size_t>(z.size())};
        const std::span<double> ws{w.data(), static_cast<std::size_t>(w.size())};
        const SqrtReport rep = block ? preconditioner.sample(op, zs, ws, 1, opt) : sqrt_apply(op, zs, ws, 1, opt);
        const Eigen::VectorXd ref = (block ? B : S) * z;
        worst = std::max(worst, (w - ref).norm() / ref.norm());
        est = std::max(est, rep.error_estimate);
        its = std::max(its, rep.iterations);
      }
      const std::string label = std::string(to_string(m)) + (block ? "+block64" : "");
      std::printf("%zu,%s,%.0e,%d,%.2e,%.2e,%.3f\n", N, label.c_str(), tol, its, est, worst, worst / tol);
    }
  }
  return 0;
}
