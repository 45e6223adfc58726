// TOML config parsing with toml++ 3.3 used header-only (TOML_HEADER_ONLY is its
// default): no link dependency leaks into the installed rpyfmm::bd target.
#include "rpyfmm/bd/config.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>
#include <set>
#include <sstream>

#include "rpyfmm/bd/gsd_trajectory.hpp"
#include "rpyfmm/bd/particles.hpp"
#include "rpyfmm/core/file_safety.hpp"
#include "rpyfmm/core/ranges.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

namespace {

[[noreturn]] void bad_key(const std::string& key, const std::string& what) {
  fail(ErrorCode::invalid_argument, "config", "key '" + key + "' " + what);
}

// Two outputs of one run in one file would interleave or replace each other: each file
// written (trajectory and log when enabled, the checkpoint always) needs its own name.
void require_distinct_output_names(const OutputSpec& o) {
  const std::pair<const char*, const std::string*> written[] = {
      {"output.trajectory", o.trajectory_every > 0 ? &o.trajectory : nullptr},
      {"output.log", o.log_every > 0 ? &o.log : nullptr},
      {"output.checkpoint", &o.checkpoint}};
  for (std::size_t i = 0; i < 3; ++i)
    for (std::size_t j = i + 1; j < 3; ++j)
      if (written[i].second && written[j].second && *written[i].second == *written[j].second)
        bad_key(written[i].first, std::string("and key '") + written[j].first + "' name the same file '" +
                                      *written[i].second + "': each output needs its own file");
}

std::string num(double v) {
  return format_number(v);
}

/// One TOML table, read key by key; finish() rejects keys nobody asked for.
class Section {
 public:
  Section(const toml::table* table, std::string name) : table_(table), name_(std::move(name)) {}

  std::string key(const std::string& k) const { return name_.empty() ? k : name_ + "." + k; }
  bool has(const std::string& k) const { return table_ && table_->contains(k); }

  const toml::node* node(const std::string& k) {
    used_.insert(k);
    return table_ ? table_->get(k) : nullptr;
  }
  double number(const std::string& k, std::optional<double> fallback = std::nullopt) {
    const toml::node* n = node(k);
    if (!n) {
      if (!fallback) bad_key(key(k), "is missing (required)");
      return *fallback;
    }
    if (!n->is_number()) bad_key(key(k), "must be a number");
    const double v = n->value<double>().value();
    if (!std::isfinite(v)) bad_key(key(k), "must be finite, got " + num(v));
    return v;
  }
  /// > 0 and not subnormal (a subnormal scale's reciprocal overflows).
  double positive(const std::string& k, std::optional<double> fallback = std::nullopt) {
    const double v = number(k, fallback);
    if (!(v > 0.0)) bad_key(key(k), "must be > 0, got " + num(v));
    if (!std::isnormal(v)) bad_key(key(k), "must be a normal number (>= 2.2e-308), got " + num(v));
    return v;
  }
  double in(const std::string& k, const ranges::RealRange& range, double fallback) {
    const double v = number(k, fallback);
    if (!range.contains(v)) {
      std::string what = "must lie in ";
      what.append(range.str()).append(", got ").append(num(v));
      bad_key(key(k), what);
    }
    return v;
  }
  /// >= 0 and, unless 0, not subnormal (a subnormal kT made every Brownian displacement 0).
  double non_negative(const std::string& k, double fallback) {
    const double v = number(k, fallback);
    if (v < 0.0) bad_key(key(k), "must be >= 0, got " + num(v));
    if (v != 0.0 && !std::isnormal(v)) bad_key(key(k), "must be 0 or a normal number (>= 2.2e-308), got " + num(v));
    return v;
  }
  /// An integer in `range` (default: any of TOML's non-negative integers).
  std::uint64_t count(const std::string& k, std::optional<std::uint64_t> fallback = std::nullopt,
                      ranges::IntRange range = {0, ranges::kI64Max}) {
    const toml::node* n = node(k);
    if (!n) {
      if (!fallback) bad_key(key(k), "is missing (required)");
      return *fallback;
    }
    if (!n->is_integer()) bad_key(key(k), "must be an integer");
    const std::int64_t v = n->value<std::int64_t>().value();
    if (v < range.lo || static_cast<std::uint64_t>(v) > range.hi)
      bad_key(key(k), "must be an integer in " + range.str() + ", got " + std::to_string(v));
    return static_cast<std::uint64_t>(v);
  }
  /// An integer in `range` that the library keeps as int.
  int int_count(const std::string& k, ranges::IntRange range) {
    range.hi = std::min<std::uint64_t>(range.hi, static_cast<std::uint64_t>(std::numeric_limits<int>::max()));
    return static_cast<int>(count(k, 0, range));
  }
  std::string string(const std::string& k, std::optional<std::string> fallback = std::nullopt) {
    const toml::node* n = node(k);
    if (!n) {
      if (!fallback) bad_key(key(k), "is missing (required)");
      return *fallback;
    }
    if (!n->is_string()) bad_key(key(k), "must be a string");
    return n->value<std::string>().value();
  }
  bool boolean(const std::string& k, bool fallback) {
    const toml::node* n = node(k);
    if (!n) return fallback;
    if (!n->is_boolean()) bad_key(key(k), "must be true or false");
    return n->value<bool>().value();
  }
  std::array<double, 3> vec3(const std::string& k, std::array<double, 3> fallback) {
    const toml::node* n = node(k);
    if (!n) return fallback;
    const toml::array* a = n->as_array();
    if (!a || a->size() != 3) bad_key(key(k), "must be an array of 3 numbers");
    std::array<double, 3> v{};
    for (std::size_t c = 0; c < 3; ++c) {
      if (!(*a)[c].is_number()) bad_key(key(k), "must be an array of 3 numbers");
      v[c] = (*a)[c].value<double>().value();
      if (!std::isfinite(v[c])) bad_key(key(k), "must be finite");
    }
    return v;
  }
  std::vector<std::string> strings(const std::string& k) {
    const toml::node* n = node(k);
    if (!n) return {};
    if (n->is_string()) return {n->value<std::string>().value()};
    const toml::array* a = n->as_array();
    if (!a) bad_key(key(k), "must be a string or an array of strings");
    std::vector<std::string> v;
    for (const auto& e : *a) {
      if (!e.is_string()) bad_key(key(k), "must be an array of strings");
      v.push_back(e.value<std::string>().value());
    }
    return v;
  }
  void finish() const {
    if (!table_) return;
    for (const auto& [k, v] : *table_) {
      const std::string s(k.str());
      if (!used_.count(s)) bad_key(key(s), "is unknown (see docs/bd-config.md)");
    }
  }

 private:
  const toml::table* table_;
  std::string name_;
  std::set<std::string> used_;
};

const toml::table* sub_table(const toml::table& root, const std::string& name) {
  const toml::node* n = root.get(name);
  if (!n) return nullptr;
  if (!n->is_table()) bad_key(name, "must be a table ([" + name + "])");
  return n->as_table();
}

std::vector<const toml::table*> table_array(const toml::table& root, const std::string& name) {
  const toml::node* n = root.get(name);
  if (!n) return {};
  const toml::array* a = n->as_array();
  if (!a) bad_key(name, "must be an array of tables ([[" + name + "]])");
  std::vector<const toml::table*> out;
  for (const auto& e : *a) {
    if (!e.is_table()) bad_key(name, "must be an array of tables ([[" + name + "]])");
    out.push_back(e.as_table());
  }
  return out;
}

// The text toml++ parses: ASCII only. toml++ 3.3 reaches TOML_UNREACHABLE (undefined behaviour)
// on some non-ASCII characters wherever it checks for whitespace: U+01CE between tokens, U+FCFF
// after a backslash in a string, U+00BA inside a malformed table header (all found by
// fuzzing). So non-ASCII bytes in comments become '?' (comments are dropped anyway) and
// anywhere else they are refused, naming line and column. Whatever this scan takes for a
// comment, toml++ never sees a non-ASCII byte.
std::string ascii_for_toml(std::string_view text, const std::string& source) {
  enum class In { code, comment, basic, literal, multi_basic, multi_literal } in = In::code;
  std::string out(text);
  std::size_t line = 1, line_start = 0;  // line_start: index of the line's first byte
  const auto at = [&](std::size_t i, std::string_view s) { return text.substr(i, s.size()) == s; };
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '\n') {
      ++line;
      line_start = i + 1;
      if (in != In::multi_basic && in != In::multi_literal) in = In::code;  // unterminated: toml++ says so
      continue;
    }
    if (static_cast<unsigned char>(c) >= 0x80) {
      if (in != In::comment) {
        fail(ErrorCode::invalid_input, "config",
             source + ":" + std::to_string(line) + ":" + std::to_string(i - line_start + 1) +
                 ": non-ASCII character (BD configs are ASCII outside comments)");
      }
      out[i] = '?';
      continue;
    }
    switch (in) {
      case In::code:
        if (c == '#') {
          in = In::comment;
        } else if (at(i, "\"\"\"") || at(i, "'''")) {
          in = c == '"' ? In::multi_basic : In::multi_literal;
          i += 2;
        } else if (c == '"' || c == '\'') {
          in = c == '"' ? In::basic : In::literal;
        }
        break;
      case In::comment:
        break;
      case In::basic:
      case In::multi_basic:
        if (c == '\\') {
          ++i;  // an escape: the next byte ends nothing (a non-ASCII one is refused above next time)
          if (i < text.size() && static_cast<unsigned char>(text[i]) >= 0x80) --i;
        } else if (in == In::basic ? c == '"' : at(i, "\"\"\"")) {
          if (in == In::multi_basic) i += 2;
          in = In::code;
        }
        break;
      case In::literal:
      case In::multi_literal:
        if (in == In::literal ? c == '\'' : at(i, "'''")) {
          if (in == In::multi_literal) i += 2;
          in = In::code;
        }
        break;
    }
  }
  return out;
}

/// The TOML table of `text` (ASCII-checked first); syntax errors name source:line:column.
toml::table parse_toml(std::string_view text, const std::string& source) {
  const std::string ascii = ascii_for_toml(text, source);
  toml::table root;
  try {
    root = toml::parse(ascii, source);
  } catch (const toml::parse_error& e) {
    std::ostringstream msg;
    msg << source << ":" << e.source().begin.line << ":" << e.source().begin.column << ": " << e.description();
    fail(ErrorCode::invalid_input, "config", msg.str());
  }
  return root;
}

/// Throws on a top-level key that is not a known section.
void require_known_sections(const toml::table& root) {
  static const std::set<std::string> sections{"system",     "types",    "particles",  "pair",   "bonds",    "external",
                                              "integrator", "mobility", "neighbours", "output", "partition"};
  for (const auto& [k, v] : root) {
    if (!sections.count(std::string(k.str())))
      bad_key(std::string(k.str()),
              "is unknown (sections: system, types, particles, pair, bonds, external, "
              "integrator, mobility, neighbours, output, partition)");
  }
}

/// Throws naming `key` (present in `s`) when rotation is off: it only acts on orientations.
void require_rotation(const Section& s, const std::string& key, const RunConfig& c) {
  if (s.has(key) && !c.integrator.rotation)
    bad_key(s.key(key), "acts on orientations: it needs system.rotation = true");
}

/// [system]: geometry, box, viscosity, kT, rotation.
void parse_system(const toml::table& root, RunConfig& c) {
  Section s(sub_table(root, "system"), "system");
  const std::string geometry = s.string("geometry", "open");
  c.viscosity = s.in("viscosity", ranges::kViscosity, 1.0);
  c.integrator.kT = s.non_negative("kT", 1.0);
  c.integrator.rotation = s.boolean("rotation", false);
  if (geometry == "periodic") {
    if (!s.has("box")) bad_key("system.box", "is missing (required for a periodic geometry)");
    const auto box = s.vec3("box", {0, 0, 0});
    for (int d = 0; d < 3; ++d)
      if (!(box[d] > 0)) bad_key("system.box", "entries must be > 0");
    c.geometry = rpy::Geometry::periodic(box[0], box[1], box[2]);
  } else if (geometry == "open") {
    if (s.has("box")) bad_key("system.box", "is only allowed with geometry = \"periodic\"");
    c.geometry = rpy::Geometry::open();
  } else {
    bad_key("system.geometry", "must be \"open\" or \"periodic\", got \"" + geometry + "\"");
  }
  s.finish();
}

/// A type's dynamics: "brownian" (no mass) or "langevin" with exactly one of mass and density;
/// the friction of a Langevin type is 6 pi eta a (free draining; docs/theory/bd.md Sec. 8).
std::optional<LangevinParticle> parse_dynamics(Section& s, const ParticleType& p, const RunConfig& c) {
  const std::string dynamics = s.string("dynamics", "brownian");
  const bool mass = s.has("mass"), density = s.has("density");
  if (dynamics == "brownian") {
    for (const char* key : {"mass", "density"})
      if (s.has(key))
        bad_key(s.key(key), "is only used with dynamics = \"langevin\" (Brownian particles have no mass)");
    return std::nullopt;
  }
  if (dynamics != "langevin")
    bad_key(s.key("dynamics"), "must be \"brownian\" or \"langevin\", got \"" + dynamics + "\"");
  if (mass == density)
    bad_key(s.key(mass ? "density" : "dynamics"), mass ? "cannot be given with mass (give one of them)"
                                                       : "= \"langevin\" needs mass or density (exactly one)");
  const double m = mass ? s.positive("mass") : sphere_mass(p.radius, s.positive("density"));
  if (!std::isnormal(m)) bad_key(s.key(mass ? "mass" : "density"), "gives the mass " + num(m) + ", out of range");
  return LangevinParticle{.mass = m, .friction = 6.0 * std::numbers::pi * c.viscosity * p.radius};
}

/// [[types]]: particle types (names unique); none keeps the default type.
void parse_types(const toml::table& root, RunConfig& c) {
  const auto tables = table_array(root, "types");
  if (!tables.empty()) {
    c.types.clear();
    c.type_torques.clear();
  }
  for (std::size_t t = 0; t < tables.size(); ++t) {
    Section s(tables[t], "types[" + std::to_string(t) + "]");
    ParticleType p;
    p.name = s.string("name");
    p.radius = s.in("radius", ranges::kRadius, 1.0);
    p.external_force = s.vec3("external_force", {0, 0, 0});
    p.surface_potential = s.number("surface_potential", 0.0);
    for (const char* key : {"external_torque", "dipole"}) require_rotation(s, key, c);
    TypeTorque rotation;
    rotation.torque = s.vec3("external_torque", {0, 0, 0});
    rotation.dipole = s.non_negative("dipole", 0.0);
    for (const auto& q : c.types)
      if (q.name == p.name) bad_key(s.key("name"), "repeats type name '" + p.name + "'");
    c.integrator.inertia.push_back(parse_dynamics(s, p, c));
    c.types.push_back(p);
    c.type_torques.push_back(rotation);
    s.finish();
  }
}

/// Throws naming `key` unless `name` is one of the particle types.
void check_type(const std::vector<ParticleType>& types, const std::string& key, const std::string& name) {
  for (const auto& t : types)
    if (t.name == name) return;
  bad_key(key, "names unknown type '" + name + "'");
}

/// [particles]: where the initial positions come from.
void parse_particles(const toml::table& root, RunConfig& c) {
  const toml::table* t = sub_table(root, "particles");
  if (!t) bad_key("particles", "is missing (required section)");
  Section s(t, "particles");
  ParticleSpec& p = c.particles;
  const std::string source_name = s.string("source");
  p.types = s.strings("types");
  for (const auto& name : p.types) check_type(c.types, "particles.types", name);
  p.seed = s.count("seed", 1);
  if (source_name == "file") {
    p.source = ParticleSpec::Source::file;
    p.file = s.string("file");
  } else if (source_name == "random" || source_name == "lattice") {
    p.source = source_name == "random" ? ParticleSpec::Source::random : ParticleSpec::Source::lattice;
    p.count = s.count("count", std::nullopt, ranges::kParticleCount);
    require_particle_count(p.count, 1, "particles.count");
    if (c.geometry.is_periodic()) {  // the box sets the region
      if (s.has("volume_fraction"))
        bad_key("particles.volume_fraction", "is only used in open geometry (the box sets the density)");
    } else {
      p.volume_fraction = s.positive("volume_fraction", 0.05);
    }
  } else if (source_name == "chains") {
    p.source = ParticleSpec::Source::chains;
    p.chains = s.count("chains");
    p.beads = s.count("beads");
    if (p.chains < 1 || p.beads < 1) bad_key("particles.chains", "and particles.beads must be >= 1");
    require_particle_count(p.chains, p.beads, "particles.chains");
    p.bond_length = s.non_negative("bond_length", 0.0);
    p.volume_fraction = s.positive("volume_fraction", 0.01);
  } else if (source_name == "clusters") {
    p.source = ParticleSpec::Source::clusters;
    p.clusters = s.count("clusters");
    p.cluster_size = s.count("cluster_size");
    if (p.clusters < 1 || p.cluster_size < 1) bad_key("particles.clusters", "and cluster_size must be >= 1");
    require_particle_count(p.clusters, p.cluster_size, "particles.clusters");
    p.volume_fraction = s.positive("volume_fraction", 0.02);
    p.cluster_volume_fraction = s.positive("cluster_volume_fraction", 0.3);
    if (p.cluster_volume_fraction > kMaxClusterVolumeFraction)
      bad_key("particles.cluster_volume_fraction", "must be <= " + num(kMaxClusterVolumeFraction));
  } else {
    bad_key("particles.source", "must be file, random, lattice, chains or clusters, got \"" + source_name + "\"");
  }
  if (p.volume_fraction > kMaxVolumeFraction)
    bad_key("particles.volume_fraction", "must be <= " + num(kMaxVolumeFraction) + ", got " + num(p.volume_fraction));
  s.finish();
}

/// The DLVO pair's short-range repulsion: core = "none" | "born", born_sigma (docs/bd-config.md).
void parse_dlvo_core(Section& s, PairPotential& p) {
  const std::string core = s.string("core", "none");
  try {
    p.core = dlvo_core_from_string(core);
  } catch (const Error&) {
    bad_key(s.key("core"), "must be none or born, got \"" + core + "\"");
  }
  if (p.core == DlvoCore::born) {
    p.born_sigma = s.has("born_sigma") ? s.positive("born_sigma") : 0.0;
  } else if (s.has("born_sigma")) {
    bad_key(s.key("born_sigma"), "needs core = \"born\"");
  }
}

/// [[pair]]: pair potentials between named types.
void parse_pairs(const toml::table& root, RunConfig& c) {
  const auto tables = table_array(root, "pair");
  for (std::size_t k = 0; k < tables.size(); ++k) {
    Section s(tables[k], "pair[" + std::to_string(k) + "]");
    NamedPair np;
    const auto names = s.strings("types");
    if (names.size() != 2) bad_key(s.key("types"), "must name two particle types, e.g. [\"A\", \"A\"]");
    check_type(c.types, s.key("types"), names[0]);
    check_type(c.types, s.key("types"), names[1]);
    np.type1 = names[0];
    np.type2 = names[1];
    try {
      np.potential.kind = pair_kind_from_string(s.string("kind"));
    } catch (const Error&) {
      bad_key(s.key("kind"), "must be lj36_18, wca, soft or dlvo");
    }
    np.potential.epsilon = s.positive("epsilon", 1.0);
    np.potential.sigma = s.non_negative("sigma", 0.0);
    np.potential.cutoff = s.non_negative("cutoff", 0.0);
    np.potential.min_distance_fraction = s.positive("min_distance_fraction", 0.8);
    if (np.potential.min_distance_fraction > 1.0) bad_key(s.key("min_distance_fraction"), "must be <= 1");
    if (np.potential.kind == PairKind::dlvo) {
      np.potential.hamaker = s.non_negative("hamaker", 0.0);
      np.potential.permittivity = s.non_negative("permittivity", 0.0);
      np.potential.kappa = s.positive("kappa");
      parse_dlvo_core(s, np.potential);
    }
    c.pairs.push_back(np);
    s.finish();
  }
}

/// [bonds]: the chain bond potential (required with particles.source = "chains").
void parse_bonds(const toml::table& root, RunConfig& c) {
  if (const toml::table* t = sub_table(root, "bonds")) {
    Section s(t, "bonds");
    BondPotential b;
    try {
      b.kind = bond_kind_from_string(s.string("kind"));
    } catch (const Error&) {
      bad_key("bonds.kind", "must be harmonic or fene");
    }
    b.k = s.positive("k");
    b.length = b.kind == BondKind::fene ? s.positive("length") : s.non_negative("length", 0.0);
    c.chain_bond = b;
    s.finish();
  }
  if (c.particles.source == ParticleSpec::Source::chains && !c.chain_bond)
    bad_key("bonds", "is missing (required with particles.source = \"chains\")");
}

/// [external]: a force on every particle; with rotation a torque on every particle and the
/// uniform field on the types' dipoles.
void parse_external(const toml::table& root, RunConfig& c) {
  Section s(sub_table(root, "external"), "external");
  c.external_force = s.vec3("force", {0, 0, 0});
  c.trap_stiffness = s.non_negative("trap_stiffness", 0.0);
  if (c.trap_stiffness > 0.0 && c.geometry.is_periodic())
    bad_key("external.trap_stiffness", "needs geometry = \"open\" (a trap at the origin has no periodic image)");
  for (const char* key : {"torque", "dipole_field"}) require_rotation(s, key, c);
  c.external_torque = s.vec3("torque", {0, 0, 0});
  c.dipole_field = s.vec3("dipole_field", {0, 0, 0});
  const bool dipoles =
      std::any_of(c.type_torques.begin(), c.type_torques.end(), [](const TypeTorque& t) { return t.dipole > 0.0; });
  if (s.has("dipole_field") && !dipoles)
    bad_key("external.dipole_field", "acts on dipoles, but no [[types]] entry sets dipole > 0");
  s.finish();
}

/// [integrator]: time step, steps, seed, displacement guard.
void parse_integrator(const toml::table& root, RunConfig& c) {
  const toml::table* t = sub_table(root, "integrator");
  if (!t) bad_key("integrator", "is missing (required section with dt and steps)");
  Section s(t, "integrator");
  c.integrator.dt = s.positive("dt");
  c.steps = s.count("steps", std::nullopt, ranges::kSteps);
  c.integrator.seed = s.count("seed", 1);
  c.integrator.max_displacement = s.positive("max_displacement", 0.5);
  c.integrator.keep_split_displacements = s.boolean("split_displacements", false);
  const std::string scheme = s.string("scheme", "naive");
  if (scheme != "naive" && scheme != "sac")
    bad_key("integrator.scheme", "must be \"naive\" or \"sac\", got \"" + scheme + "\"");
  c.integrator.sac.enabled = scheme == "sac";
  if (s.has("adsorption_factor") && !c.integrator.sac.enabled)
    bad_key("integrator.adsorption_factor", "is only used with scheme = \"sac\"");
  c.integrator.sac.adsorption_factor = s.positive("adsorption_factor", 1.05);
  s.finish();
}

/// [mobility]: the operator (rpy::MobilitySpec) and its square-root sampler.
void parse_mobility(const toml::table& root, RunConfig& c) {
  Section s(sub_table(root, "mobility"), "mobility");
  try {
    c.mobility.method = rpy::mobility_method_from_string(s.string("method", "auto"));
  } catch (const Error&) {
    bad_key("mobility.method", "must be none, direct, fmm, pse or auto");
  }
  c.mobility.tolerance = s.in("tolerance", ranges::kMobilityTolerance, 1e-3);
  c.mobility.fmm_crossover = s.count("fmm_crossover", 0);
  c.mobility.fft_measure = s.boolean("fft_measure", false);
  try {
    c.mobility.wave_precision = rpy::pse::wave_precision_from_name(s.string("wave_precision", "auto"));
  } catch (const Error&) {
    bad_key("mobility.wave_precision", "must be auto, single or double");
  }
  try {
    c.mobility.device = rpy::compute_device_from_string(s.string("device", "cpu"));
  } catch (const Error&) {
    bad_key("mobility.device", "must be cpu or cuda");
  }
  c.mobility.viscosity = c.viscosity;
  c.mobility.geometry = c.geometry;
  try {
    c.integrator.sqrt.method = rpy::sqrt_method_from_string(s.string("sqrt_method", "automatic"));
  } catch (const Error&) {
    bad_key("mobility.sqrt_method", "must be automatic, lanczos, chebyshev, cholesky, eigen or split");
  }
  c.integrator.sqrt.tolerance = s.in("sqrt_tolerance", ranges::kSolverTolerance, c.mobility.tolerance);
  c.integrator.sqrt.max_iterations = s.int_count("sqrt_max_iterations", ranges::kSqrtIterations);
  try {
    c.integrator.sqrt.preconditioner =
        rpy::sqrt_preconditioner_from_string(s.string("sqrt_preconditioner", "automatic"));
  } catch (const Error&) {
    bad_key("mobility.sqrt_preconditioner", "must be automatic, block or none");
  }
  c.integrator.sqrt.preconditioner_block = s.int_count("sqrt_preconditioner_block", ranges::kPreconditionerBlock);
  if (c.integrator.sqrt.preconditioner == rpy::SqrtPreconditioner::block &&
      c.integrator.sqrt.method != rpy::SqrtMethod::lanczos && c.integrator.sqrt.method != rpy::SqrtMethod::chebyshev &&
      c.integrator.sqrt.method != rpy::SqrtMethod::automatic)
    bad_key("mobility.sqrt_preconditioner", "block needs sqrt_method lanczos, chebyshev or automatic");
  s.finish();
}

/// Langevin types move without hydrodynamic interactions, rotation or split displacements: each
/// combination is refused naming the first Langevin type's dynamics key.
void check_langevin(const RunConfig& c) {
  const auto& inertia = c.integrator.inertia;
  const auto first = std::find_if(inertia.begin(), inertia.end(), [](const auto& t) { return t.has_value(); });
  if (first == inertia.end()) return;
  const std::string key = "types[" + std::to_string(first - inertia.begin()) + "].dynamics";
  if (c.mobility.method != rpy::MobilityMethod::none)
    bad_key(key,
            "= \"langevin\" needs [mobility] method = \"none\" (free draining): hydrodynamic interactions "
            "with inertia are not supported");
  if (c.integrator.rotation) bad_key(key, "= \"langevin\" does not support system.rotation yet");
  if (c.integrator.keep_split_displacements)
    bad_key(key, "= \"langevin\" cannot be used with integrator.split_displacements (it splits Brownian steps)");
}

/// The SAC scheme (Algorithm 2 of Tran et al. (2015)) needs carriers (Langevin types) and
/// adsorbers (Brownian types), free draining, no rotation and no bonds: each is refused naming
/// integrator.scheme.
void check_sac(const RunConfig& c) {
  if (!c.integrator.sac.enabled) return;
  const auto& inertia = c.integrator.inertia;
  const auto carriers = std::count_if(inertia.begin(), inertia.end(), [](const auto& t) { return t.has_value(); });
  const std::string key = "integrator.scheme";
  if (carriers == 0) bad_key(key, "= \"sac\" needs a carrier type ([[types]] dynamics = \"langevin\"); none is given");
  if (static_cast<std::size_t>(carriers) == c.types.size())
    bad_key(key, "= \"sac\" needs an adsorbing type ([[types]] dynamics = \"brownian\"); every type is Langevin");
  if (c.mobility.method != rpy::MobilityMethod::none)
    bad_key(key, "= \"sac\" needs [mobility] method = \"none\" (it replaces hydrodynamic interactions)");
  if (c.integrator.rotation) bad_key(key, "= \"sac\" does not support system.rotation");
  if (c.chain_bond) bad_key(key, "= \"sac\" does not support bonds ([bonds], particles.source = \"chains\")");
}

/// [neighbours]: list skin and rebuild policy.
void parse_neighbours(const toml::table& root, RunConfig& c) {
  Section s(sub_table(root, "neighbours"), "neighbours");
  c.neighbours.skin = s.non_negative("skin", 0.0);
  c.neighbours.fixed_interval = s.int_count("fixed_interval", {0, ranges::kI64Max});
  s.finish();
}

/// partition.repartition_imbalance: a number >= 1, or inf (TOML's infinity: never repartition).
double repartition_imbalance(Section& s) {
  const std::string k = "repartition_imbalance";
  const toml::node* n = s.node(k);
  if (!n) return PartitionSpec{}.repartition_imbalance;
  if (!n->is_number()) bad_key(s.key(k), "must be a number >= 1 or inf");
  const double v = n->value<double>().value();
  if (!(v >= 1.0)) bad_key(s.key(k), "must be >= 1 (or inf: never), got " + num(v));
  return v;
}

/// [partition]: the curve and repartition policy of a run across MPI ranks.
void parse_partition(const toml::table& root, RunConfig& c) {
  Section s(sub_table(root, "partition"), "partition");
  const std::string curve = s.string("curve", "morton");
  if (curve != "morton" && curve != "hilbert")
    bad_key("partition.curve", "must be \"morton\" or \"hilbert\", got \"" + curve + "\"");
  c.partition.curve = curve == "hilbert" ? PartitionSpec::Curve::hilbert : PartitionSpec::Curve::morton;
  c.partition.repartition_imbalance = repartition_imbalance(s);
  const std::string cost = s.string("repartition_cost", "model");
  if (cost != "model" && cost != "measured_time")
    bad_key("partition.repartition_cost", "must be \"model\" or \"measured_time\", got \"" + cost + "\"");
  c.partition.repartition_cost = cost == "model" ? PartitionSpec::Cost::model : PartitionSpec::Cost::measured_time;
  s.finish();
}

/// output.format: "xyz" or "gsd" (the latter only in builds with GSD support).
TrajectoryFormat trajectory_format(const std::string& name) {
  if (name == "xyz") return TrajectoryFormat::xyz;
  if (name != "gsd") bad_key("output.format", "must be \"xyz\" or \"gsd\", got \"" + name + "\"");
  if (!gsd_supported()) bad_key("output.format", "= \"gsd\" cannot be written: " + gsd_unsupported_reason());
  return TrajectoryFormat::gsd;
}

/// [output]: directory, trajectory format, file names and intervals.
void parse_output(const toml::table& root, RunConfig& c) {
  Section s(sub_table(root, "output"), "output");
  c.output.dir = s.string("dir", "bd-out");
  if (c.output.dir.empty()) bad_key("output.dir", "must not be empty");
  const std::string format = s.string("format", "xyz");
  c.output.format = trajectory_format(format);
  c.output.trajectory = s.string("trajectory", "trajectory." + format);
  c.output.log = s.string("log", "log.csv");
  c.output.checkpoint = s.string("checkpoint", "checkpoint.bin");
  c.output.trajectory_every = s.count("trajectory_every", 100);
  c.output.log_every = s.count("log_every", 10);
  c.output.checkpoint_every = s.count("checkpoint_every", 1000);
  for (const auto* name : {&c.output.trajectory, &c.output.log, &c.output.checkpoint})
    if (name->empty() || name->find('/') != std::string::npos)
      bad_key("output", "file names must be plain names inside output.dir");
  require_distinct_output_names(c.output);
  s.finish();
}

}  // namespace

RunConfig parse_config(std::string_view text, const std::string& source) {
  const toml::table root = parse_toml(text, source);
  require_known_sections(root);
  RunConfig c;
  c.text = std::string(text);
  c.source = source;
  parse_system(root, c);
  parse_types(root, c);
  parse_particles(root, c);
  parse_pairs(root, c);
  parse_bonds(root, c);
  parse_external(root, c);
  parse_integrator(root, c);
  parse_mobility(root, c);
  check_sac(c);
  check_langevin(c);
  parse_neighbours(root, c);
  parse_output(root, c);
  parse_partition(root, c);
  return c;
}

RunConfig load_config(const std::filesystem::path& path) {
  require_regular_input(path, "config");  // a device or FIFO would be read forever
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(ErrorCode::io_error, "config", "cannot read '" + path.string() + "'");
  std::ostringstream s;
  s << in.rdbuf();
  return parse_config(s.str(), path.string());
}

std::string_view demo_config_text() {
  return R"(# rpyfmm bd built-in demo: a cloud of 2000 spheres sedimenting under gravity
# with hydrodynamic interactions (direct RPY). The cloud falls faster than a
# single sphere (collective drag reduction) and slowly loses particles from its tail.
[system]
geometry = "open"
viscosity = 1.0
kT = 1.0

[[types]]
name = "sphere"
radius = 1.0
external_force = [0.0, 0.0, -1.0]   # buoyant weight (kT = 1, a = 1 units)

[particles]
source = "random"          # a spherical cloud... generated as a random suspension
count = 2000
volume_fraction = 0.05
seed = 1

[[pair]]
types = ["sphere", "sphere"]
kind = "wca"               # short-range repulsion keeps spheres apart
epsilon = 1.0

[integrator]
dt = 0.01
steps = 150
seed = 2024
max_displacement = 0.5

[mobility]
method = "auto"            # direct below default_fmm_crossover particles, fmm from there
tolerance = 1e-3

[output]
dir = "bd-demo"
trajectory_every = 20
log_every = 10
checkpoint_every = 100
)";
}

ForceField make_force_field(const RunConfig& config) {
  ForceField ff(config.types);
  for (const auto& p : config.pairs) ff.set_pair(ff.type_index(p.type1), ff.type_index(p.type2), p.potential);
  ff.set_global_force(config.external_force);
  ff.set_trap(config.trap_stiffness);
  if (config.integrator.rotation)
    ff.set_torque_field(TorqueField(config.type_torques, config.external_torque, config.dipole_field));
  if (config.chain_bond) ff.add_bond_potential(*config.chain_bond);
  return ff;
}

}  // namespace rpyfmm::bd
