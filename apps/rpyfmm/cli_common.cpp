#include "cli_common.hpp"

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <omp.h>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {

void add_common_options(CLI::App& cmd, CommonOptions& options) {
  cmd.add_option("--threads", options.threads, "OpenMP threads (0 = default)");
  cmd.add_flag("--json", options.json, "print one line of JSON with parameters and timings");
}

void apply_threads(const CommonOptions& options) {
  require(options.threads >= 0, ErrorCode::invalid_argument, "--threads",
          "must be >= 0, got " + std::to_string(options.threads));
  if (options.threads > 0) omp_set_num_threads(options.threads);
}

int active_threads() { return omp_get_max_threads(); }

std::string json_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out += c;
        }
    }
  }
  return out;
}

namespace {
std::string number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}
}  // namespace

JsonLine& JsonLine::add(const std::string& key, const std::string& value) {
  items_.emplace_back(key, "\"" + json_escape(value) + "\"");
  return *this;
}
JsonLine& JsonLine::add(const std::string& key, double value) {
  items_.emplace_back(key, number(value));
  return *this;
}
JsonLine& JsonLine::add(const std::string& key, long long value) {
  items_.emplace_back(key, std::to_string(value));
  return *this;
}
JsonLine& JsonLine::add(const std::string& key, bool value) {
  items_.emplace_back(key, value ? "true" : "false");
  return *this;
}
JsonLine& JsonLine::add(const std::string& key, const std::map<std::string, double>& values) {
  std::string s = "{";
  bool first = true;
  for (const auto& [k, v] : values) {
    s += (first ? "\"" : ",\"") + json_escape(k) + "\":" + number(v);
    first = false;
  }
  items_.emplace_back(key, s + "}");
  return *this;
}
JsonLine& JsonLine::add(const std::string& key, const std::vector<double>& values) {
  std::string s = "[";
  for (std::size_t i = 0; i < values.size(); ++i) s += (i ? "," : "") + number(values[i]);
  items_.emplace_back(key, s + "]");
  return *this;
}
std::string JsonLine::str() const {
  std::string s = "{";
  for (std::size_t i = 0; i < items_.size(); ++i) {
    s += (i ? ",\"" : "\"") + json_escape(items_[i].first) + "\":" + items_[i].second;
  }
  return s + "}";
}

}  // namespace rpyfmm::cli
