// The order in which FmmRpy evaluates its near field: leaf pairs grouped into tasks, tasks into
// colours, so that each pair of adjacent leaves is evaluated once for both directions (the RPY
// block is symmetric, M_ji = M_ij) without races and with results that do not depend on the
// thread count.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

namespace rpyfmm::rpy::detail {

/// Task t belongs to leaf `leaf[t]` and writes the velocities of that leaf and of its symmetric
/// partners only:
///  - one-sided source leaves one_sided[one_begin[t] .. one_begin[t+1]) act on the leaf's
///    targets (the leaf itself, and pairs whose reverse is not in the list);
///  - symmetric partners symmetric[sym_begin[t] .. sym_begin[t+1]) are leaves B for which both
///    (leaf, B) and (B, leaf) are near-field pairs: the task evaluates both directions.
/// Tasks are stored colour by colour: colour c holds tasks [colour_begin[c], colour_begin[c+1]).
/// No two tasks of one colour write the same leaf, so a colour runs in parallel; colours run in
/// order, and every velocity receives its contributions in one fixed order.
struct NearSchedule {
  std::vector<std::uint32_t> leaf;
  std::vector<std::size_t> one_begin;
  std::vector<std::uint32_t> one_sided;
  std::vector<std::size_t> sym_begin;
  std::vector<std::uint32_t> symmetric;
  std::vector<std::size_t> colour_begin;

  [[nodiscard]] std::size_t num_tasks() const noexcept { return leaf.size(); }
  [[nodiscard]] std::size_t num_colours() const noexcept { return colour_begin.empty() ? 0 : colour_begin.size() - 1; }
};

/// Schedule for the directed near-field leaf pairs (target leaf, source leaf), each listed once,
/// over num_leaves leaves. With use_symmetry = false every pair is one-sided and all tasks share
/// one colour (each task writes its own leaf only). With use_symmetry = true, a pair whose
/// reverse is also listed is owned by its lower-numbered leaf, and tasks are coloured greedily in
/// leaf order so that no two tasks of a colour write a common leaf.
NearSchedule make_near_schedule(const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs,
                                std::size_t num_leaves, bool use_symmetry);

/// Runs task(state, leaf, one_sided, partners) for every task of the schedule: colours in order,
/// the tasks of one colour in parallel, with one ThreadState per thread. No two tasks of a colour
/// write the same leaf, and each output receives its contributions in a fixed order, so results
/// do not depend on the thread count.
template <class ThreadState, class Task>
void for_each_near_task(const NearSchedule& plan, const Task& task) {
#pragma omp parallel
  {
    ThreadState state;
    for (std::size_t c = 0; c < plan.num_colours(); ++c) {
      const auto t0 = static_cast<std::int64_t>(plan.colour_begin[c]);
      const auto t1 = static_cast<std::int64_t>(plan.colour_begin[c + 1]);
#pragma omp for schedule(dynamic, 1)
      for (std::int64_t tt = t0; tt < t1; ++tt) {
        const auto t = static_cast<std::size_t>(tt);
        const std::span<const std::uint32_t> one(plan.one_sided.data() + plan.one_begin[t],
                                                 plan.one_begin[t + 1] - plan.one_begin[t]);
        const std::span<const std::uint32_t> partners(plan.symmetric.data() + plan.sym_begin[t],
                                                      plan.sym_begin[t + 1] - plan.sym_begin[t]);
        task(state, plan.leaf[t], one, partners);
      }
    }
  }
}

}  // namespace rpyfmm::rpy::detail
