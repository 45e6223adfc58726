// rpyfmm CLI — pieces shared by the subcommands: thread count, one-line JSON.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

namespace CLI {
class App;
}

namespace rpyfmm::cli {

/// Options every subcommand has.
struct CommonOptions {
  int threads = 0;   // 0 = OpenMP default
  bool json = false; // print one line of JSON to stdout
};

/// Adds --threads and --json to `cmd`.
void add_common_options(CLI::App& cmd, CommonOptions& options);
/// Applies --threads (omp_set_num_threads) after validating it.
void apply_threads(const CommonOptions& options);
/// Threads that OpenMP will use.
int active_threads();

/// A flat JSON object built key by key and printed on one line.
class JsonLine {
 public:
  JsonLine& add(const std::string& key, const std::string& value);
  JsonLine& add(const std::string& key, const char* value) { return add(key, std::string(value)); }
  JsonLine& add(const std::string& key, double value);
  JsonLine& add(const std::string& key, long long value);
  JsonLine& add(const std::string& key, int value) { return add(key, static_cast<long long>(value)); }
  JsonLine& add(const std::string& key, std::size_t value) { return add(key, static_cast<long long>(value)); }
  JsonLine& add(const std::string& key, bool value);
  JsonLine& add(const std::string& key, const std::map<std::string, double>& values);
  JsonLine& add(const std::string& key, const std::vector<double>& values);
  [[nodiscard]] std::string str() const;

 private:
  std::vector<std::pair<std::string, std::string>> items_;
};

std::string json_escape(const std::string& s);

}  // namespace rpyfmm::cli
