#include "cli_common.hpp"

#include <omp.h>

#include <CLI/CLI.hpp>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <utility>

#include "rpyfmm/core/threads.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {

void add_common_options(CLI::App& cmd, CommonOptions& options) {
  // The range of rpyfmm::require_thread_count (threads.hpp), which apply_threads applies too.
  add_integer_option(cmd, "--threads", options.threads, {0, static_cast<std::uint64_t>(max_threads())},
                     "OpenMP threads, 0 = default; at most 4 x the hardware threads and never more than " +
                         std::to_string(kThreadCeiling));
  cmd.add_flag("--json", options.json, "print one line of JSON with parameters and timings");
}

void add_io_option(CLI::App& cmd, std::string& io) {
  cmd.add_option("--io", io,
                 "across MPI ranks: 'collective' (default) every rank reads and writes its share of the .npy "
                 "arrays with MPI-IO, 'root' rank 0 reads and writes them whole")
      ->check(CLI::IsMember({"root", "collective"}));
}

void apply_threads(const CommonOptions& options) {
  require_thread_count(options.threads, "--threads", /*allow_zero=*/true);
  if (options.threads > 0) omp_set_num_threads(static_cast<int>(options.threads));
}

void refuse_empty_values(CLI::App& app) {
  const CLI::Validator non_empty(
      [](const std::string& value) {
        return value.empty() ? std::string("must not be empty (it names no file or choice)") : std::string();
      },
      "");
  for (CLI::Option* option : app.get_options())
    if (option->get_type_name() == "TEXT") option->check(non_empty);
  for (CLI::App* command : app.get_subcommands({})) refuse_empty_values(*command);
}

namespace {

// A decimal integer as read: its sign and magnitude (every value of the int64 and uint64 ranges).
struct ParsedInteger {
  bool negative = false;
  std::uint64_t magnitude = 0;
  /// The value as T; T holds it (add_integer checks that the range fits T).
  template <class T>
  [[nodiscard]] T as() const {
    if (!negative) return static_cast<T>(magnitude);
    return static_cast<T>(-static_cast<std::int64_t>(magnitude - 1) - 1);  // magnitude <= 2^63
  }
};

// `text` if it is a decimal integer (optional sign) in `range`; otherwise a CLI::ValidationError
// naming the option (main prints it on one line and exits with 2).
ParsedInteger parse_integer(const std::string& text, const std::string& name, ranges::IntRange range) {
  ParsedInteger v;
  v.negative = !text.empty() && text[0] == '-';
  const char* first = text.data() + ((v.negative || (!text.empty() && text[0] == '+')) ? 1 : 0);
  const char* last = text.data() + text.size();
  const auto [end, ec] = std::from_chars(first, last, v.magnitude);
  const std::string expect = "must be an integer in " + range.str();
  if (first == last || ec == std::errc::invalid_argument || end != last)
    throw CLI::ValidationError(name, expect + ", got '" + text + "'");
  if (v.negative && v.magnitude == 0) v.negative = false;  // "-0"
  constexpr std::uint64_t kMaxNegative = std::uint64_t{1} << 63;
  const bool in_range =
      ec != std::errc::result_out_of_range &&
      (v.negative ? v.magnitude <= kMaxNegative && std::cmp_greater_equal(v.as<std::int64_t>(), range.lo)
                  : std::cmp_greater_equal(v.magnitude, range.lo) && v.magnitude <= range.hi);
  if (!in_range) throw CLI::ValidationError(name, expect + ", got " + text);
  return v;
}

template <class T>
CLI::Option* add_integer(CLI::App& cmd, const std::string& name, T& target, ranges::IntRange range,
                         const std::string& help) {
  // The range must fit T, so that the checked value converts exactly.
  if (std::cmp_less(range.lo, std::numeric_limits<T>::min()) ||
      std::cmp_greater(range.hi, std::numeric_limits<T>::max()))
    throw std::logic_error("add_integer_option: range of " + name + " does not fit its type");
  auto* option = cmd.add_option_function<std::string>(
      name, [&target, name, range](const std::string& text) { target = parse_integer(text, name, range).as<T>(); },
      help + " (integer in " + range.str() + ")");
  option->type_name("INT")->default_str(std::to_string(target));
  return option;
}

}  // namespace

CLI::Option* add_integer_option(CLI::App& cmd, const std::string& name, int& target, ranges::IntRange range,
                                const std::string& help) {
  return add_integer(cmd, name, target, range, help);
}
CLI::Option* add_integer_option(CLI::App& cmd, const std::string& name, long long& target, ranges::IntRange range,
                                const std::string& help) {
  return add_integer(cmd, name, target, range, help);
}
CLI::Option* add_integer_option(CLI::App& cmd, const std::string& name, std::uint64_t& target, ranges::IntRange range,
                                const std::string& help) {
  return add_integer(cmd, name, target, range, help);
}

namespace {

std::vector<std::string>& pending_warnings() {
  static std::vector<std::string> warnings;
  return warnings;
}

}  // namespace

void print_pending_warnings() {
  for (const std::string& w : pending_warnings()) std::cerr << "rpyfmm: warning: " << w << '\n';
  pending_warnings().clear();
}

bool RenamedOption::given() const {
  return option->count() + deprecated->count() > 0;
}

RenamedOption add_renamed_option(CLI::App& cmd, const std::string& name, const std::string& old_name, double& target,
                                 const std::string& help) {
  RenamedOption r;
  r.option = cmd.add_option(name, target, help);
  // Option callbacks run after parsing in the order the options were added: `target` then holds
  // the value of `name` when it was given.
  CLI::Option* current = r.option;
  r.deprecated = cmd.add_option_function<double>(
      old_name,
      [current, &target, name, old_name](const double& value) {
        require(current->count() == 0 || value == target, ErrorCode::invalid_argument, name,
                old_name + " (its deprecated spelling) was given a different value");
        pending_warnings().push_back(old_name + " is deprecated; use " + name);
        target = value;
      },
      "deprecated spelling of " + name);
  r.deprecated->group("Deprecated spellings");  // listed apart in --help (a hidden option has no name in errors)
  return r;
}

Error nonfinite_output(std::size_t index, bool nan, const std::string& what) {
  return Error(ErrorCode::numerical_failure, what + ": entry " + std::to_string(index) + " of the result is " +
                                                 (nan ? "NaN" : "infinite") +
                                                 " (nothing written; are the input's scales extreme?)");
}

void require_finite_output(std::span<const double> values, const std::string& what) {
  for (std::size_t i = 0; i < values.size(); ++i)
    if (!std::isfinite(values[i])) throw nonfinite_output(i, std::isnan(values[i]), what);
}

int active_threads() {
  return omp_get_max_threads();
}

std::string json_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
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
JsonLine& JsonLine::add(const std::string& key, std::uint64_t value) {
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
