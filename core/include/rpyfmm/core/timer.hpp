// rpyfmm — wall-clock stage timers used for the per-stage breakdowns that
// solvers report to callers (FMM stages, PSE stages, BD step parts).
#pragma once

#include <chrono>
#include <map>
#include <string>

namespace rpyfmm {

class StopWatch {
 public:
  StopWatch() : start_(clock::now()) {}
  void restart() { start_ = clock::now(); }
  [[nodiscard]] double seconds() const { return std::chrono::duration<double>(clock::now() - start_).count(); }

 private:
  using clock = std::chrono::steady_clock;
  clock::time_point start_;
};

/// Named stage times in seconds, accumulated over calls.
using StageTimes = std::map<std::string, double>;

}  // namespace rpyfmm
