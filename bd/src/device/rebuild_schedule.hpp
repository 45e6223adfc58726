// rpyfmm::bd::device — when the Verlet lists are rebuilt: NeighbourList::update's decision, kept on
// the host. The first step builds; then, without pair forces never again; with a fixed interval
// every `interval` steps (the Table 1 strategy of Tran et al. (2015), for comparison); otherwise when the
// last step's update found a particle beyond skin/2 of its position at the last build (its
// Algorithm 1, lines 15-16: the device reports that in the step's status, one read per step).
#pragma once

#include <cstddef>

namespace rpyfmm::bd::device {

class RebuildSchedule {
 public:
  RebuildSchedule(double cutoff, int fixed_interval) : cutoff_(cutoff), interval_(fixed_interval) {}

  /// Whether the step about to run must rebuild; counts the step as one with or without a build.
  bool next_step() {
    const bool due =
        !built_ || (cutoff_ > 0.0 && (interval_ > 0 ? since_build_ >= static_cast<std::size_t>(interval_) : moved_));
    if (due) {
      built_ = true;
      moved_ = false;
      since_build_ = 1;
      ++rebuilds_;
    } else {
      ++since_build_;
    }
    return due;
  }
  /// The dynamic test's answer for the positions a good step produced.
  void set_moved(bool moved) { moved_ = moved; }
  /// True when steps test the displacements (a cut-off and no fixed interval).
  [[nodiscard]] bool dynamic() const { return cutoff_ > 0.0 && interval_ == 0; }
  [[nodiscard]] std::size_t rebuilds() const { return rebuilds_; }

 private:
  double cutoff_;
  int interval_;
  bool built_ = false;
  bool moved_ = false;
  std::size_t since_build_ = 0;
  std::size_t rebuilds_ = 0;
};

}  // namespace rpyfmm::bd::device
