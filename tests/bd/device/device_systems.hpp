// Test systems for the BD device stages (bd/src/device): configurations (random, clustered,
// jittered lattices, open or periodic, positions unwrapped across the faces) and force fields
// with every pair potential the CPU engine has, mixtures with a cut-off per pair of types, bonds,
// external forces and a trap; the Integrator options of their free-draining runs.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/potentials.hpp"

namespace device_test {

using rpyfmm::bd::BondKind;
using rpyfmm::bd::BondPotential;
using rpyfmm::bd::ForceField;
using rpyfmm::bd::PairKind;
using rpyfmm::bd::PairPotential;
using rpyfmm::bd::ParticleType;

/// The Integrator options of a run with time step dt at kT, keyed by seed, on `engine`.
inline rpyfmm::bd::IntegratorOptions integrator_options(double dt, double kT, std::uint64_t seed,
                                                        rpyfmm::bd::StepEngine engine = rpyfmm::bd::StepEngine::cpu) {
  rpyfmm::bd::IntegratorOptions o;
  o.dt = dt;
  o.kT = kT;
  o.seed = seed;
  o.engine = engine;
  return o;
}

/// n points uniform in [0, L)^3.
inline std::vector<double> uniform_cloud(std::size_t n, double L, unsigned seed) {
  std::mt19937_64 gen(seed);
  std::uniform_real_distribution<double> u(0.0, L);
  std::vector<double> x(3 * n);
  for (double& v : x) v = u(gen);
  return x;
}

/// n points in a few dense Gaussian clusters (width `width`) spread over [0, L)^3: rows of very
/// different lengths, many cells empty.
inline std::vector<double> clustered_cloud(std::size_t n, double L, double width, unsigned seed) {
  std::mt19937_64 gen(seed);
  std::uniform_real_distribution<double> u(0.0, L);
  std::normal_distribution<double> g(0.0, width);
  std::vector<std::array<double, 3>> centres(5);
  for (auto& c : centres) c = {u(gen), u(gen), u(gen)};
  std::vector<double> x(3 * n);
  for (std::size_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) x[3 * i + c] = centres[i % centres.size()][c] + g(gen);
  return x;
}

/// A simple cubic lattice of side `side` points, spacing h, each point moved by up to +-jitter per
/// coordinate: no two points closer than h - 2 sqrt(3) jitter.
inline std::vector<double> jittered_lattice(int side, double h, double jitter, unsigned seed) {
  std::mt19937_64 gen(seed);
  std::uniform_real_distribution<double> u(-jitter, jitter);
  std::vector<double> x;
  for (int a = 0; a < side; ++a)
    for (int b = 0; b < side; ++b)
      for (int c = 0; c < side; ++c)
        for (int k : {a, b, c}) x.push_back((k + 0.5) * h + u(gen));
  return x;
}

/// The lattice spacing at which every pair potential of single_type(kind) acts between nearest
/// neighbours without overlaps: inside the cut-off, outside the hard core (DLVO: outside contact,
/// r > a_i + a_j = 2); mixture(): 1.6.
inline double spacing(PairKind kind) {
  switch (kind) {
    case PairKind::lj36_18:
    case PairKind::wca:
      return 2.15;
    case PairKind::soft:
      return 1.9;
    case PairKind::dlvo:
      return 2.3;
  }
  return 2.15;
}

/// Shifts every third particle by a whole box vector (positions unwrapped, as the CPU engine keeps
/// them: the stages must take the minimum image and the wrap themselves).
inline void unwrap_some(std::vector<double>& x, double L) {
  for (std::size_t i = 0; i < x.size() / 3; i += 3) {
    x[3 * i] += L * static_cast<double>(1 + static_cast<int>(i % 2));
    x[3 * i + 2] -= L;
  }
}

/// One type of radius 1 with the pair potential `kind` (epsilon 14 kT for lj36_18, as
/// Tran et al. (2015); DLVO with a Born core in reduced units).
inline ForceField single_type(PairKind kind) {
  ForceField f({ParticleType{"A", 1.0, {0.0, 0.0, 0.0}, 0.04}});
  PairPotential p;
  p.kind = kind;
  p.epsilon = kind == PairKind::lj36_18 ? 14.0 : 2.0;
  if (kind == PairKind::dlvo) {
    p.hamaker = 3.0;
    p.permittivity = 4000.0;
    p.kappa = 5.0;
    p.core = rpyfmm::bd::DlvoCore::born;
  }
  f.set_pair(0, 0, p);
  return f;
}

/// Two types (radii 1 and 0.6, external forces) with a different potential and cut-off per pair:
/// A-A lj36_18 (sigma 1.5, r_c 2.25), A-B soft (sigma 1.8 = r_c), B-B wca (sigma 1.2, r_c 1.35).
inline ForceField mixture() {
  ForceField f({ParticleType{"A", 1.0, {0.0, 0.0, -0.5}, 0.0}, ParticleType{"B", 0.6, {0.2, 0.0, 0.0}, 0.0}});
  PairPotential aa;
  aa.kind = PairKind::lj36_18;
  aa.epsilon = 14.0;
  aa.sigma = 1.5;
  PairPotential ab;
  ab.kind = PairKind::soft;
  ab.epsilon = 30.0;
  ab.sigma = 1.8;
  PairPotential bb;
  bb.kind = PairKind::wca;
  bb.sigma = 1.2;
  f.set_pair(0, 0, aa);
  f.set_pair(0, 1, ab);
  f.set_pair(1, 1, bb);
  return f;
}

/// Types 0, 1, 0, 1, ...
inline std::vector<std::uint32_t> alternating_types(std::size_t n) {
  std::vector<std::uint32_t> t(n);
  for (std::size_t i = 0; i < n; ++i) t[i] = static_cast<std::uint32_t>(i % 2);
  return t;
}

/// Harmonic (rest length 1.8) and FENE (R0 6) bonds along consecutive particles (i, i + 1), i even.
inline void add_chain_bonds(ForceField& f, std::size_t n) {
  const std::uint32_t harmonic = f.add_bond_potential(BondPotential{BondKind::harmonic, 20.0, 1.8});
  const std::uint32_t fene = f.add_bond_potential(BondPotential{BondKind::fene, 5.0, 6.0});
  std::vector<rpyfmm::bd::Bond> bonds;
  for (std::uint32_t i = 0; i + 1 < n; i += 2) bonds.push_back({i, i + 1, (i / 2) % 2 == 0 ? harmonic : fene});
  f.add_bonds(bonds);
}

}  // namespace device_test
