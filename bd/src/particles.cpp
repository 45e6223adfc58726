#include "rpyfmm/bd/particles.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>
#include <unordered_map>

#include "rpyfmm/core/file_safety.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

namespace {

constexpr double kGap = 1.02;  // generated particles keep r >= 1.02 (a_i + a_j)

/// Uniform [0, 1) from a 64-bit engine, identical on every platform.
double uniform(std::mt19937_64& gen) {
  return static_cast<double>(gen() >> 11) * 0x1.0p-53;
}

/// Random point in a ball of radius R (rejection from the cube).
std::array<double, 3> in_ball(std::mt19937_64& gen, double R) {
  for (;;) {
    std::array<double, 3> p{};
    for (double& v : p) v = (2 * uniform(gen) - 1) * R;
    if (p[0] * p[0] + p[1] * p[1] + p[2] * p[2] <= R * R) return p;
  }
}

/// Spatial hash for overlap tests during random sequential addition. Cells of edge >= the
/// largest contact distance, so a candidate's overlaps lie in its 27 surrounding cells; in a
/// periodic box the cell indices wrap (cells of edge L / floor(L / contact) per axis), so images
/// across the faces are found the same way (each test is O(1), not O(N) near a face).
class Placer {
 public:
  Placer(double max_radius, const rpy::Geometry& g) : geometry_(g) {
    const double contact = 2 * kGap * max_radius;
    for (int c = 0; c < 3; ++c) {
      if (geometry_.is_periodic()) {
        const double L = geometry_.box()[c];
        cells_per_axis_[c] = std::max<long>(1, static_cast<long>(std::floor(L / contact)));
        cell_[c] = L / static_cast<double>(cells_per_axis_[c]);
      } else {
        cell_[c] = contact;
      }
    }
  }
  bool fits(std::array<double, 3> p, double a) const {
    wrap(p);
    const auto k = key_of(p);
    for (long dx = -1; dx <= 1; ++dx)
      for (long dy = -1; dy <= 1; ++dy)
        for (long dz = -1; dz <= 1; ++dz) {
          auto it = cells_.find(pack(neighbour_key(k, {dx, dy, dz})));
          if (it == cells_.end()) continue;
          for (std::size_t j : it->second) {
            double r2 = 0;
            for (int c = 0; c < 3; ++c) {
              double d = p[c] - x_[3 * j + c];
              if (geometry_.is_periodic()) d -= geometry_.box()[c] * std::nearbyint(d / geometry_.box()[c]);
              r2 += d * d;
            }
            const double contact = kGap * (a + radius_[j]);
            if (r2 < contact * contact) return false;
          }
        }
    return true;
  }
  void add(std::array<double, 3> p, double a) {
    wrap(p);
    cells_[pack(key_of(p))].push_back(radius_.size());
    x_.insert(x_.end(), p.begin(), p.end());
    radius_.push_back(a);
  }
  std::vector<double>& positions() { return x_; }

 private:
  void wrap(std::array<double, 3>& p) const {
    if (!geometry_.is_periodic()) return;
    for (int c = 0; c < 3; ++c) {
      const double L = geometry_.box()[c];
      p[c] -= L * std::floor(p[c] / L);
      if (p[c] >= L) p[c] = 0.0;
    }
  }
  std::array<long, 3> key_of(const std::array<double, 3>& p) const {
    std::array<long, 3> k{};
    for (int c = 0; c < 3; ++c) {
      k[c] = static_cast<long>(std::floor(p[c] / cell_[c]));
      if (geometry_.is_periodic()) k[c] = std::clamp(k[c], 0L, cells_per_axis_[c] - 1);  // p in [0, L)
    }
    return k;
  }
  /// The cell at offset o from cell k (wrapped in a periodic box; with fewer than 3 cells along
  /// an axis some offsets name the same cell, which is then searched twice: harmless).
  std::array<long, 3> neighbour_key(const std::array<long, 3>& k, const std::array<long, 3>& o) const {
    std::array<long, 3> n{};
    for (int c = 0; c < 3; ++c) {
      n[c] = k[c] + o[c];
      if (geometry_.is_periodic()) n[c] = ((n[c] % cells_per_axis_[c]) + cells_per_axis_[c]) % cells_per_axis_[c];
    }
    return n;
  }
  static std::int64_t pack(const std::array<long, 3>& k) {
    return ((static_cast<std::int64_t>(k[0]) & 0x1FFFFF) << 42) | ((static_cast<std::int64_t>(k[1]) & 0x1FFFFF) << 21) |
           (static_cast<std::int64_t>(k[2]) & 0x1FFFFF);
  }
  std::array<double, 3> cell_{};
  std::array<long, 3> cells_per_axis_{1, 1, 1};
  rpy::Geometry geometry_;
  std::unordered_map<std::int64_t, std::vector<std::size_t>> cells_;
  std::vector<double> x_;
  std::vector<double> radius_;
};

std::vector<std::uint32_t> assign_types(const RunConfig& c, const ForceField& ff, std::size_t n) {
  std::vector<std::uint32_t> t(n, 0);
  if (c.particles.types.empty()) return t;
  std::vector<std::uint32_t> idx;
  for (const auto& name : c.particles.types) idx.push_back(ff.type_index(name));
  for (std::size_t i = 0; i < n; ++i) t[i] = idx[i % idx.size()];
  return t;
}

double mean_volume(const ForceField& ff, const std::vector<std::uint32_t>& types) {
  double v = 0;
  for (auto t : types) v += 4.0 / 3.0 * std::numbers::pi * std::pow(ff.types()[t].radius, 3);
  return v;
}

double max_radius(const ForceField& ff) {
  double a = 0;
  for (const auto& t : ff.types()) a = std::max(a, t.radius);
  return a;
}

/// Random sequential addition of particles with `types`; `propose` draws a candidate.
template <class Propose>
std::vector<double> place(const RunConfig& c, const ForceField& ff, const std::vector<std::uint32_t>& types,
                          Propose&& propose, const char* key) {
  Placer placer(max_radius(ff), c.geometry);
  for (std::size_t i = 0; i < types.size(); ++i) {
    const double a = ff.types()[types[i]].radius;
    bool placed = false;
    for (int attempt = 0; attempt < 20000 && !placed; ++attempt) {
      const auto p = propose(i, placer.positions());
      if (placer.fits(p, a)) {
        placer.add(p, a);
        placed = true;
      }
    }
    if (!placed)
      fail(ErrorCode::invalid_argument, "config",
           std::string("key '") + key + "': could not place particle " + std::to_string(i) +
               " without overlaps (volume fraction too high for random insertion; lower it)");
  }
  return std::move(placer.positions());
}

}  // namespace

namespace {

/// The number in `field` of row `where`; `what` names it in errors (non-numbers, NaN, Inf).
double parse_number(const std::string& field, const std::string& where, const std::string& what) {
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(field, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != field.size())
    fail(ErrorCode::invalid_input, "particles.file", where + ": '" + field + "' is not a number");
  if (!std::isfinite(v)) fail(ErrorCode::invalid_input, "particles.file", where + ": " + what + " is not finite");
  return v;
}

/// The type in `field`: an index below the number of types, or a type name.
std::uint32_t parse_type(const std::string& f, const ForceField& forces, const std::string& where) {
  if (!f.empty() && std::all_of(f.begin(), f.end(), [](char ch) { return ch >= '0' && ch <= '9'; })) {
    const unsigned long t = std::stoul(f);
    if (t >= forces.types().size())
      fail(ErrorCode::invalid_input, "particles.file", where + ": type index " + f + " is not defined");
    return static_cast<std::uint32_t>(t);
  }
  try {
    return forces.type_index(f);
  } catch (const Error&) {
    fail(ErrorCode::invalid_input, "particles.file", where + ": unknown type '" + f + "'");
  }
}

/// Appends the orientation w x y z of `fields` [first, first + 4) to s (zero refused).
void add_orientation(const std::vector<std::string>& fields, std::size_t first, const std::string& where,
                     InitialState& s) {
  double norm2 = 0.0;
  for (std::size_t c = 0; c < 4; ++c) {
    const double v =
        parse_number(fields[first + c], where,
                     "orientation component " + std::to_string(c) + " of particle " + std::to_string(s.types.size()));
    s.orientations.push_back(v);
    norm2 += v * v;
  }
  if (!(norm2 > 1e-24))
    fail(ErrorCode::invalid_input, "particles.file",
         where + ": the orientation of particle " + std::to_string(s.types.size()) + " is a zero quaternion");
}

}  // namespace

InitialState read_particle_file(const std::filesystem::path& path, const ForceField& forces) {
  require_regular_input(path, "particles.file");  // a device or FIFO would be read forever
  std::ifstream in(path);
  if (!in) fail(ErrorCode::io_error, "particles.file", "cannot read '" + path.string() + "'");
  InitialState s;
  std::string line;
  std::size_t lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    if (auto hash = line.find('#'); hash != std::string::npos) line.resize(hash);
    std::istringstream row(line);
    std::vector<std::string> fields;
    for (std::string f; row >> f;) fields.push_back(f);
    if (fields.empty()) continue;
    const std::string where = path.string() + ":" + std::to_string(lineno);
    const std::size_t count = fields.size();
    if (count != 3 && count != 4 && count != 7 && count != 8)
      fail(ErrorCode::invalid_input, "particles.file",
           where + ": expected 'x y z [type] [qw qx qy qz]', got " + std::to_string(count) + " fields");
    const bool oriented = count >= 7;
    if (!s.types.empty() && oriented != !s.orientations.empty())
      fail(ErrorCode::invalid_input, "particles.file",
           where + ": orientation columns on some rows only (give them on every row or on none)");
    for (int c = 0; c < 3; ++c)
      s.positions.push_back(parse_number(
          fields[c], where, "coordinate " + std::to_string(c) + " of particle " + std::to_string(s.types.size())));
    const bool typed = count == 4 || count == 8;
    if (oriented) add_orientation(fields, typed ? 4 : 3, where, s);
    s.types.push_back(typed ? parse_type(fields[3], forces, where) : 0);
  }
  if (s.types.empty()) fail(ErrorCode::invalid_input, "particles.file", "'" + path.string() + "' has no particles");
  return s;
}

namespace {

/// A uniform point in the periodic box L (three draws, x first).
std::array<double, 3> in_box(std::mt19937_64& gen, const std::array<double, 3>& L) {
  return {uniform(gen) * L[0], uniform(gen) * L[1], uniform(gen) * L[2]};
}

/// Radius of the ball that `volume` fills to volume fraction phi: volume / (4/3 pi R^3) = phi.
double ball_radius(double volume, double phi) {
  return std::cbrt(volume / phi * 3.0 / (4.0 * std::numbers::pi));
}

/// source = "random": uniform in the box, or in a spherical cloud of volume fraction phi (open).
InitialState random_particles(const RunConfig& c, const ForceField& ff, std::mt19937_64& gen) {
  const ParticleSpec& p = c.particles;
  const bool periodic = c.geometry.is_periodic();
  InitialState s;
  s.types = assign_types(c, ff, p.count);
  const double R = periodic ? 0.0 : ball_radius(mean_volume(ff, s.types), p.volume_fraction);
  if (periodic) {
    const double phi = mean_volume(ff, s.types) / c.geometry.volume();
    if (phi > 0.4)
      fail(ErrorCode::invalid_argument, "config",
           "key 'particles.count': " + std::to_string(p.count) + " particles fill " + format_number(phi) +
               " of the box (max 0.4 for random insertion)");
  }
  s.positions = place(
      c, ff, s.types,
      [&](std::size_t, const std::vector<double>&) {
        return periodic ? in_box(gen, c.geometry.box()) : in_ball(gen, R);
      },
      "particles.volume_fraction");
  return s;
}

/// source = "lattice": a cubic lattice filling the box, or of volume fraction phi (open).
InitialState lattice_particles(const RunConfig& c, const ForceField& ff) {
  const ParticleSpec& p = c.particles;
  const bool periodic = c.geometry.is_periodic();
  const auto& L = c.geometry.box();
  InitialState s;
  s.types = assign_types(c, ff, p.count);
  const auto side = static_cast<std::size_t>(std::ceil(std::cbrt(static_cast<double>(p.count)) - 1e-9));
  std::array<double, 3> h{};
  for (int d = 0; d < 3; ++d)
    h[d] = periodic ? L[d] / static_cast<double>(side)
                    : std::cbrt(mean_volume(ff, s.types) / static_cast<double>(p.count) / p.volume_fraction);
  const double amax = max_radius(ff);
  if (*std::min_element(h.begin(), h.end()) < 2 * amax * kGap)
    fail(ErrorCode::invalid_argument, "config",
         "key 'particles.count': lattice spacing " + format_number(h[0]) + " < 2 a (particles would overlap)");
  for (std::size_t i = 0; i < p.count; ++i) {
    const std::size_t ix = i % side, iy = (i / side) % side, iz = i / (side * side);
    s.positions.insert(s.positions.end(),
                       {(static_cast<double>(ix) + 0.5) * h[0], (static_cast<double>(iy) + 0.5) * h[1],
                        (static_cast<double>(iz) + 0.5) * h[2]});
  }
  return s;
}

/// source = "chains": self-avoiding random walks of bond length b from random starts, bonded
/// bead to bead.
InitialState chain_particles(const RunConfig& c, const ForceField& ff, std::mt19937_64& gen) {
  const ParticleSpec& p = c.particles;
  const bool periodic = c.geometry.is_periodic();
  InitialState s;
  s.types = assign_types(c, ff, p.chains * p.beads);
  const double a = max_radius(ff);
  const double b = p.bond_length > 0 ? p.bond_length : 2.1 * a;
  if (b < 2 * a * kGap)
    fail(ErrorCode::invalid_argument, "config", "key 'particles.bond_length' must be >= 2.04 a (beads would overlap)");
  const double R = periodic ? 0.0 : ball_radius(mean_volume(ff, s.types), p.volume_fraction);
  s.positions = place(
      c, ff, s.types,
      [&](std::size_t i, const std::vector<double>& placed) {
        if (i % p.beads == 0) return periodic ? in_box(gen, c.geometry.box()) : in_ball(gen, R);
        // A self-avoiding random walk step of length b.
        const double u = 2 * uniform(gen) - 1, phi = 2 * std::numbers::pi * uniform(gen);
        const double sxy = std::sqrt(1 - u * u);
        const double* last = &placed[3 * (i - 1)];
        return std::array<double, 3>{last[0] + b * sxy * std::cos(phi), last[1] + b * sxy * std::sin(phi),
                                     last[2] + b * u};
      },
      "particles.volume_fraction");
  for (std::size_t ch = 0; ch < p.chains; ++ch)  // bonds between consecutive beads of each chain
    for (std::size_t k = 1; k < p.beads; ++k)
      s.bonds.push_back(
          {static_cast<std::uint32_t>(ch * p.beads + k - 1), static_cast<std::uint32_t>(ch * p.beads + k), 0});
  return s;
}

/// source = "clusters": balls of cluster_volume_fraction around random centres.
InitialState cluster_particles(const RunConfig& c, const ForceField& ff, std::mt19937_64& gen) {
  const ParticleSpec& p = c.particles;
  const bool periodic = c.geometry.is_periodic();
  const std::size_t n = p.clusters * p.cluster_size;
  InitialState s;
  s.types = assign_types(c, ff, n);
  const double v = mean_volume(ff, s.types) / static_cast<double>(n);
  const double rc = ball_radius(static_cast<double>(p.cluster_size) * v, p.cluster_volume_fraction);
  const double R = periodic ? 0.0 : ball_radius(static_cast<double>(n) * v, p.volume_fraction);
  std::vector<std::array<double, 3>> centres(p.clusters);
  for (auto& ctr : centres) ctr = periodic ? in_box(gen, c.geometry.box()) : in_ball(gen, std::max(0.0, R - rc));
  s.positions = place(
      c, ff, s.types,
      [&](std::size_t i, const std::vector<double>&) {
        auto q = in_ball(gen, rc);
        const auto& ctr = centres[i / p.cluster_size];
        for (int d = 0; d < 3; ++d) q[d] += ctr[d];
        return q;
      },
      "particles.cluster_volume_fraction");
  return s;
}

}  // namespace

InitialState make_particles(const RunConfig& c, const ForceField& ff) {
  check_particle_spec(c.particles, c.geometry.is_periodic());
  std::mt19937_64 gen(c.particles.seed);
  switch (c.particles.source) {
    case ParticleSpec::Source::file: {
      InitialState s = read_particle_file(c.particles.file, ff);
      if (!s.orientations.empty() && !c.integrator.rotation)
        fail(ErrorCode::invalid_input, "particles.file",
             "'" + c.particles.file.string() + "' has orientation columns, which need system.rotation = true");
      return s;
    }
    case ParticleSpec::Source::random:
      return random_particles(c, ff, gen);
    case ParticleSpec::Source::lattice:
      return lattice_particles(c, ff);
    case ParticleSpec::Source::chains:
      return chain_particles(c, ff, gen);
    case ParticleSpec::Source::clusters:
      return cluster_particles(c, ff, gen);
  }
  return {};
}

}  // namespace rpyfmm::bd
