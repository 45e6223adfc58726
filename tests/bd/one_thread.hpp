// Test helper: one OpenMP thread while alive. Statistical and restart tests step few particles
// many times, where thread start-up dominates (on a loaded machine by far); BD results do not
// depend on the thread count (docs/reproducibility.md), so nothing they check changes.
#pragma once

#include <omp.h>

namespace bdtest {

class OneThread {
 public:
  OneThread() : saved_(omp_get_max_threads()) { omp_set_num_threads(1); }
  OneThread(const OneThread&) = delete;
  OneThread& operator=(const OneThread&) = delete;
  ~OneThread() { omp_set_num_threads(saved_); }

 private:
  int saved_;
};

}  // namespace bdtest
