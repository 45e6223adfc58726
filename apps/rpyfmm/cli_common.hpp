// rpyfmm CLI — pieces shared by the subcommands: thread count, strictly parsed integer
// options, the finiteness check of results, one-line JSON.
#pragma once

#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "rpyfmm/core/error.hpp"
#include "rpyfmm/core/ranges.hpp"

namespace CLI {
class App;
class Option;
}  // namespace CLI

namespace rpyfmm::cli {

/// Options every subcommand has.
struct CommonOptions {
  long long threads = 0;  // 0 = OpenMP default
  bool json = false;      // print one line of JSON to stdout
};

/// Adds --threads and --json to `cmd`.
void add_common_options(CLI::App& cmd, CommonOptions& options);
/// Adds --io root|collective (`io`, default collective): who reads and writes the .npy arrays of a
/// run across MPI ranks (docs/mpi.md, "The command-line tool under mpirun"); one process ignores it.
void add_io_option(CLI::App& cmd, std::string& io);
/// Applies --threads (omp_set_num_threads) after validating it (rpyfmm::require_thread_count).
void apply_threads(const CommonOptions& options);

/// Gives every text option of `app` and its commands (paths, method names) a check that refuses
/// an empty value: "--out ''" or "--config ''" would otherwise read as "not given" (an optional
/// output silently not written, the built-in demo run instead of a config) or fail late with a
/// message about a temporary file.
void refuse_empty_values(CLI::App& app);
/// Threads that OpenMP will use.
int active_threads();

/// Adds an integer option parsed strictly: decimal digits with an optional sign, and a value in
/// `range`. Anything else (a negative count, a value past the type, "1e3", "12abc") is refused
/// while parsing, one line naming the option and the range, never wrapped or truncated. The
/// help text gets the range appended and shows the current value of `target` as the default.
CLI::Option* add_integer_option(CLI::App& cmd, const std::string& name, int& target, ranges::IntRange range,
                                const std::string& help);
CLI::Option* add_integer_option(CLI::App& cmd, const std::string& name, long long& target, ranges::IntRange range,
                                const std::string& help);
CLI::Option* add_integer_option(CLI::App& cmd, const std::string& name, std::uint64_t& target, ranges::IntRange range,
                                const std::string& help);

/// A real option under its name in the one vocabulary for accuracy (`--tolerance`,
/// `--sqrt-tolerance`, `--solver-tolerance`) plus its former spelling (`--eps`, `--tol`,
/// `--sqrt-tol`), listed apart in --help. Both write `target`; the former one queues the warning
/// "rpyfmm: warning: --eps is deprecated; use --tolerance" (print_pending_warnings), and both given
/// with different values is an error naming them.
struct RenamedOption {
  CLI::Option* option = nullptr;      ///< the current name
  CLI::Option* deprecated = nullptr;  ///< the former spelling
  /// True when either spelling was given (after parsing).
  [[nodiscard]] bool given() const;
};
RenamedOption add_renamed_option(CLI::App& cmd, const std::string& name, const std::string& old_name, double& target,
                                 const std::string& help);
/// Prints the queued warnings to stderr, one line each. A command calls it first when it runs, so
/// that a command line refused while parsing still gives one line on stderr: the error.
void print_pending_warnings();

/// Throws rpyfmm::Error (numerical_failure) naming `what` and the first entry that is NaN or
/// infinite: every command calls it on its results before writing any of them, so that exit
/// status 0 never comes with non-finite output.
void require_finite_output(std::span<const double> values, const std::string& what);
/// require_finite_output's error for entry `index` of the result (NaN where `nan`, else infinite).
Error nonfinite_output(std::size_t index, bool nan, const std::string& what);

/// A flat JSON object built key by key and printed on one line.
class JsonLine {
 public:
  JsonLine& add(const std::string& key, const std::string& value);
  JsonLine& add(const std::string& key, const char* value) { return add(key, std::string(value)); }
  JsonLine& add(const std::string& key, double value);
  JsonLine& add(const std::string& key, long long value);
  JsonLine& add(const std::string& key, int value) { return add(key, static_cast<long long>(value)); }
  JsonLine& add(const std::string& key, std::uint64_t value);  // exact up to 2^64-1
  JsonLine& add(const std::string& key, bool value);
  JsonLine& add(const std::string& key, const std::map<std::string, double>& values);
  JsonLine& add(const std::string& key, const std::vector<double>& values);
  [[nodiscard]] std::string str() const;

 private:
  std::vector<std::pair<std::string, std::string>> items_;
};

std::string json_escape(const std::string& s);

}  // namespace rpyfmm::cli
