// Every default that docs/bd-config.md states in its key tables equals the default that the
// config parser applies (bd::parse_config on a config that sets only the required keys), and the
// description of the built-in demo matches its config and the `auto` crossover.
//
// A table row is `| `key`[, `key2`...] | default[, default2...] | meaning |`. A default is
// checked when it starts with a backticked literal (`1.0`, `"auto"`, `[0,0,0]`, `false`);
// "required", "—" and prose are not defaults. A row whose literal has no check below fails,
// so a key added to the docs gets a check here too.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/potentials.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace {

using rpyfmm::bd::RunConfig;

/// One stated default: `section.key` and its literal without backticks.
struct Stated {
  std::string key, literal;
};

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  const auto e = s.find_last_not_of(" \t");
  return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::stringstream in(s);
  for (std::string part; std::getline(in, part, sep);) out.push_back(trim(part));
  return out;
}

/// The first backticked token of `cell`, if the cell starts with one.
bool leading_literal(const std::string& cell, std::string& literal) {
  if (cell.size() < 2 || cell[0] != '`') return false;
  const auto end = cell.find('`', 1);
  if (end == std::string::npos) return false;
  literal = cell.substr(1, end - 1);
  return true;
}

/// Section name of a heading "## `[name]` ..." or "## `[[name]]` ...", else "".
std::string section_of(const std::string& line) {
  static const std::regex heading(R"(^## `\[\[?([a-z_]+)\]?\]`)");
  std::smatch m;
  return std::regex_search(line, m, heading) ? m[1].str() : std::string();
}

/// Defaults of one table row: several keys pair up with comma-separated defaults; a key with
/// per-source defaults ("random, lattice: `0.05`; chains: `0.01`") yields "key@source" entries.
void read_row(const std::string& section, const std::string& line, std::vector<Stated>& out) {
  const auto cells = split(line, '|');  // "", keys, defaults, meaning, ""
  if (cells.size() < 4 || cells[1].empty() || cells[1][0] != '`') return;
  const auto keys = split(cells[1], ',');
  if (keys.size() == 1 && cells[2].find(':') != std::string::npos && cells[2].find(';') != std::string::npos) {
    for (const auto& part : split(cells[2], ';')) {
      const auto colon = part.find(':');
      std::string literal;
      if (!leading_literal(trim(part.substr(colon + 1)), literal)) continue;
      for (const auto& source : split(part.substr(0, colon), ','))
        out.push_back({section + "." + keys[0].substr(1, keys[0].size() - 2) + "@" + source, literal});
    }
    return;
  }
  const auto defaults = keys.size() == 1 ? std::vector<std::string>{cells[2]} : split(cells[2], ',');
  for (std::size_t k = 0; k < keys.size() && k < defaults.size(); ++k) {
    std::string literal;
    if (leading_literal(defaults[k], literal))
      out.push_back({section + "." + keys[k].substr(1, keys[k].size() - 2), literal});
  }
}

std::vector<Stated> stated_defaults() {
  std::ifstream in(std::string(RPYFMM_SOURCE_DIR) + "/docs/bd-config.md");
  EXPECT_TRUE(in.good()) << "cannot read docs/bd-config.md";
  std::vector<Stated> out;
  std::string section;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("## ", 0) == 0) section = section_of(line);
    if (!section.empty() && line.rfind("| `", 0) == 0) read_row(section, line, out);
  }
  return out;
}

/// A config with only the required keys (and one pair, so that the pair defaults apply).
RunConfig minimal_config(const std::string& particles = "source = \"random\"\ncount = 8\n") {
  const std::string text = "[particles]\n" + particles +
                           "[[pair]]\ntypes = [\"A\", \"A\"]\nkind = \"wca\"\n"
                           "[bonds]\nkind = \"harmonic\"\nk = 1.0\n"
                           "[integrator]\ndt = 0.01\nsteps = 1\n";
  return rpyfmm::bd::parse_config(text, "<minimal>");
}

double number(const std::string& literal) {
  return std::stod(literal);
}

std::string unquoted(const std::string& literal) {
  return literal.size() >= 2 && literal.front() == '"' ? literal.substr(1, literal.size() - 2) : literal;
}

bool vec3_equals(const std::string& literal, const std::array<double, 3>& v) {
  const auto parts = split(literal.substr(1, literal.size() - 2), ',');
  return parts.size() == 3 && number(parts[0]) == v[0] && number(parts[1]) == v[1] && number(parts[2]) == v[2];
}

bool flag(const std::string& literal) {
  return literal == "true";
}

/// The DLVO pair of a config that names no core (kappa 0.5, Hamaker constant 3).
rpyfmm::bd::PairPotential dlvo_pair() {
  const std::string text =
      "[particles]\nsource = \"random\"\ncount = 8\n"
      "[[pair]]\ntypes = [\"A\", \"A\"]\nkind = \"dlvo\"\nhamaker = 3.0\nkappa = 0.5\n"
      "[integrator]\ndt = 0.01\nsteps = 1\n";
  return rpyfmm::bd::parse_config(text, "<dlvo>").pairs.at(0).potential;
}

using Check = std::function<bool(const RunConfig&, const std::string&)>;

/// How each documented key is read back from a parsed config.
const std::map<std::string, Check>& checks() {
  namespace bd = rpyfmm::bd;
  namespace rpy = rpyfmm::rpy;
  static const std::map<std::string, Check> table{
      {"system.geometry", [](const RunConfig& c,
                             const std::string& l) { return c.geometry.is_periodic() == (unquoted(l) == "periodic"); }},
      {"system.viscosity", [](const RunConfig& c, const std::string& l) { return c.viscosity == number(l); }},
      {"system.kT", [](const RunConfig& c, const std::string& l) { return c.integrator.kT == number(l); }},
      {"system.rotation", [](const RunConfig& c, const std::string& l) { return c.integrator.rotation == flag(l); }},
      {"types.radius", [](const RunConfig& c, const std::string& l) { return c.types.at(0).radius == number(l); }},
      {"types.external_force",
       [](const RunConfig& c, const std::string& l) { return vec3_equals(l, c.types.at(0).external_force); }},
      {"types.surface_potential",
       [](const RunConfig& c, const std::string& l) { return c.types.at(0).surface_potential == number(l); }},
      {"types.external_torque",
       [](const RunConfig& c, const std::string& l) { return vec3_equals(l, c.type_torques.at(0).torque); }},
      {"types.dipole",
       [](const RunConfig& c, const std::string& l) { return c.type_torques.at(0).dipole == number(l); }},
      {"particles.bond_length",
       [](const RunConfig&, const std::string& l) {
         return minimal_config("source = \"chains\"\nchains = 1\nbeads = 2\n").particles.bond_length == number(l);
       }},
      {"particles.cluster_volume_fraction",
       [](const RunConfig&, const std::string& l) {
         return minimal_config("source = \"clusters\"\nclusters = 1\ncluster_size = 2\n")
                    .particles.cluster_volume_fraction == number(l);
       }},
      {"particles.seed", [](const RunConfig& c, const std::string& l) { return c.particles.seed == std::stoull(l); }},
      {"particles.volume_fraction@random",
       [](const RunConfig& c, const std::string& l) { return c.particles.volume_fraction == number(l); }},
      {"particles.volume_fraction@lattice",
       [](const RunConfig&, const std::string& l) {
         return minimal_config("source = \"lattice\"\ncount = 8\n").particles.volume_fraction == number(l);
       }},
      {"particles.volume_fraction@chains",
       [](const RunConfig&, const std::string& l) {
         return minimal_config("source = \"chains\"\nchains = 1\nbeads = 2\n").particles.volume_fraction == number(l);
       }},
      {"particles.volume_fraction@clusters",
       [](const RunConfig&, const std::string& l) {
         return minimal_config("source = \"clusters\"\nclusters = 1\ncluster_size = 2\n").particles.volume_fraction ==
                number(l);
       }},
      {"pair.epsilon",
       [](const RunConfig& c, const std::string& l) { return c.pairs.at(0).potential.epsilon == number(l); }},
      {"pair.sigma",
       [](const RunConfig& c, const std::string& l) { return c.pairs.at(0).potential.sigma == number(l); }},
      {"pair.min_distance_fraction",
       [](const RunConfig& c, const std::string& l) {
         return c.pairs.at(0).potential.min_distance_fraction == number(l);
       }},
      {"pair.hamaker", [](const RunConfig&, const std::string& l) { return bd::PairPotential{}.hamaker == number(l); }},
      {"pair.permittivity",
       [](const RunConfig&, const std::string& l) { return bd::PairPotential{}.permittivity == number(l); }},
      {"pair.core", [](const RunConfig&, const std::string& l) { return unquoted(l) == to_string(dlvo_pair().core); }},
      // "0.8 / kappa": the resolved Born prefactor A sigma_B^6 / 37800 with sigma_B = 0.8 / kappa.
      {"pair.born_sigma",
       [](const RunConfig&, const std::string& l) {
         bd::PairPotential p = dlvo_pair();
         p.core = bd::DlvoCore::born;
         const double sigma_b = 0.8 / p.kappa;
         const double expected = p.hamaker * std::pow(sigma_b, 6) / 37800.0;
         const double got = bd::resolve_pair(p, 1.0, 1.0, 0.0, 0.0).born_prefactor;
         return l == "0.8 / kappa" && std::abs(got - expected) <= 1e-12 * expected;
       }},
      {"integrator.seed", [](const RunConfig& c, const std::string& l) { return c.integrator.seed == std::stoull(l); }},
      {"integrator.max_displacement",
       [](const RunConfig& c, const std::string& l) { return c.integrator.max_displacement == number(l); }},
      {"integrator.split_displacements",
       [](const RunConfig& c, const std::string& l) { return c.integrator.keep_split_displacements == flag(l); }},
      {"integrator.scheme",
       [](const RunConfig& c, const std::string& l) { return !c.integrator.sac.enabled && unquoted(l) == "naive"; }},
      {"integrator.adsorption_factor",
       [](const RunConfig& c, const std::string& l) { return c.integrator.sac.adsorption_factor == number(l); }},
      {"mobility.method",
       [](const RunConfig& c, const std::string& l) {
         return c.mobility.method == rpy::mobility_method_from_string(unquoted(l));
       }},
      {"mobility.tolerance",
       [](const RunConfig& c, const std::string& l) { return c.mobility.tolerance == number(l); }},
      {"mobility.fmm_crossover",
       [](const RunConfig& c, const std::string& l) { return c.mobility.fmm_crossover == std::stoull(l); }},
      {"mobility.fft_measure",
       [](const RunConfig& c, const std::string& l) { return c.mobility.fft_measure == flag(l); }},
      {"mobility.wave_precision",
       [](const RunConfig& c, const std::string& l) {
         return c.mobility.wave_precision == rpy::pse::wave_precision_from_name(unquoted(l));
       }},
      {"mobility.device",
       [](const RunConfig& c, const std::string& l) {
         return c.mobility.device == rpy::compute_device_from_string(unquoted(l));
       }},
      {"mobility.sqrt_method",
       [](const RunConfig& c, const std::string& l) {
         return c.integrator.sqrt.method == rpy::sqrt_method_from_string(unquoted(l));
       }},
      {"mobility.sqrt_max_iterations",
       [](const RunConfig& c, const std::string& l) { return c.integrator.sqrt.max_iterations == std::stoi(l); }},
      {"mobility.sqrt_preconditioner",
       [](const RunConfig& c, const std::string& l) {
         return c.integrator.sqrt.preconditioner == rpy::sqrt_preconditioner_from_string(unquoted(l));
       }},
      {"mobility.sqrt_preconditioner_block",
       [](const RunConfig& c, const std::string& l) { return c.integrator.sqrt.preconditioner_block == std::stoi(l); }},
      {"neighbours.skin", [](const RunConfig& c, const std::string& l) { return c.neighbours.skin == number(l); }},
      {"neighbours.fixed_interval",
       [](const RunConfig& c, const std::string& l) { return c.neighbours.fixed_interval == std::stoi(l); }},
      {"partition.curve",
       [](const RunConfig& c, const std::string& l) {
         return c.partition.curve == bd::PartitionSpec::Curve::morton && unquoted(l) == "morton";
       }},
      {"partition.repartition_imbalance",
       [](const RunConfig& c, const std::string& l) { return c.partition.repartition_imbalance == number(l); }},
      {"partition.repartition_cost",
       [](const RunConfig& c, const std::string& l) {
         return c.partition.repartition_cost == bd::PartitionSpec::Cost::model && unquoted(l) == "model";
       }},
      {"output.dir", [](const RunConfig& c, const std::string& l) { return c.output.dir == unquoted(l); }},
      {"output.format",
       [](const RunConfig& c, const std::string& l) {
         return c.output.format == rpyfmm::bd::TrajectoryFormat::xyz && unquoted(l) == "xyz";
       }},
      {"output.trajectory",
       [](const RunConfig& c, const std::string& l) { return c.output.trajectory == unquoted(l); }},
      {"output.trajectory_every",
       [](const RunConfig& c, const std::string& l) { return c.output.trajectory_every == std::stoull(l); }},
      {"output.log", [](const RunConfig& c, const std::string& l) { return c.output.log == unquoted(l); }},
      {"output.log_every",
       [](const RunConfig& c, const std::string& l) { return c.output.log_every == std::stoull(l); }},
      {"output.checkpoint",
       [](const RunConfig& c, const std::string& l) { return c.output.checkpoint == unquoted(l); }},
      {"output.checkpoint_every",
       [](const RunConfig& c, const std::string& l) { return c.output.checkpoint_every == std::stoull(l); }},
  };
  return table;
}

TEST(DocsBdConfig, StatedDefaultsMatchTheParser) {
  const RunConfig config = minimal_config();
  const auto stated = stated_defaults();
  std::size_t checked = 0;
  for (const auto& s : stated) {
    const auto it = checks().find(s.key);
    if (it == checks().end()) {
      ADD_FAILURE() << "docs/bd-config.md states a default for '" << s.key << "' (" << s.literal
                    << ") that this test does not check: add a check";
      continue;
    }
    EXPECT_TRUE(it->second(config, s.literal))
        << "docs/bd-config.md: '" << s.key << "' defaults to " << s.literal << ", the parser disagrees";
    ++checked;
  }
  // Every check still has its row in the docs (a deleted row would silently drop a default).
  EXPECT_EQ(checked, checks().size()) << "a key checked here lost its default in docs/bd-config.md";
}

TEST(DocsBdConfig, SqrtToleranceDefaultsToTheMobilityTolerance) {
  const RunConfig config = minimal_config();
  EXPECT_EQ(config.integrator.sqrt.tolerance, config.mobility.tolerance);  // "= `tolerance`"
}

TEST(DocsBdConfig, BuiltInDemoIsAsDescribed) {
  // docs/bd-config.md: 2000 spheres, auto at tolerance 1e-3, FMM because the 3-digit crossover
  // (1500 on every machine) is at most 2000 particles.
  const RunConfig demo = rpyfmm::bd::parse_config(rpyfmm::bd::demo_config_text(), "<built-in demo>");
  EXPECT_EQ(demo.particles.count, 2000u);
  EXPECT_EQ(demo.mobility.method, rpyfmm::rpy::MobilityMethod::automatic);
  EXPECT_EQ(demo.mobility.tolerance, 1e-3);
  EXPECT_EQ(rpyfmm::rpy::default_fmm_crossover(demo.mobility.tolerance), 1500u);
  EXPECT_LE(rpyfmm::rpy::default_fmm_crossover(demo.mobility.tolerance), demo.particles.count);
}

}  // namespace
