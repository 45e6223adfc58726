// FmmRpy's near-field schedule (near_schedule.hpp): ownership of symmetric leaf pairs and a
// greedy colouring of the tasks by the leaves they write.
#include "near_schedule.hpp"

#include <algorithm>

namespace rpyfmm::rpy::detail {

NearSchedule make_near_schedule(const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs,
                                std::size_t num_leaves, bool use_symmetry) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> sorted = pairs;
  std::sort(sorted.begin(), sorted.end());
  auto listed = [&](std::uint32_t a, std::uint32_t b) {
    return std::binary_search(sorted.begin(), sorted.end(), std::make_pair(a, b));
  };

  // Per leaf: one-sided sources and owned symmetric partners (both in ascending order).
  std::vector<std::vector<std::uint32_t>> one(num_leaves), sym(num_leaves);
  for (const auto& [a, b] : sorted) {
    if (use_symmetry && a != b && listed(b, a)) {
      if (a < b) sym[a].push_back(b);  // the pair (b, a) is the same block, owned by a
    } else {
      one[a].push_back(b);
    }
  }

  // Tasks: every leaf with work, in leaf order; writes(t) = {leaf} + its symmetric partners.
  std::vector<std::uint32_t> task_leaf;
  for (std::uint32_t l = 0; l < num_leaves; ++l)
    if (!one[l].empty() || !sym[l].empty()) task_leaf.push_back(l);
  const std::size_t ntasks = task_leaf.size();

  // Greedy colouring in task order: a task takes the smallest colour that no earlier task
  // writing one of its leaves has.
  std::vector<int> colour(ntasks, 0);
  if (use_symmetry) {
    std::vector<std::vector<std::uint32_t>> writers(num_leaves);  // tasks already coloured, per leaf
    std::vector<std::size_t> seen;                                // colour -> last task that forbade it
    for (std::size_t t = 0; t < ntasks; ++t) {
      const std::uint32_t l = task_leaf[t];
      auto forbid = [&](std::uint32_t leaf) {
        for (std::uint32_t w : writers[leaf]) {
          const auto c = static_cast<std::size_t>(colour[w]);
          if (c >= seen.size()) seen.resize(c + 1, ntasks);
          seen[c] = t;
        }
      };
      forbid(l);
      for (std::uint32_t b : sym[l]) forbid(b);
      std::size_t c = 0;
      while (c < seen.size() && seen[c] == t) ++c;
      colour[t] = static_cast<int>(c);
      writers[l].push_back(static_cast<std::uint32_t>(t));
      for (std::uint32_t b : sym[l]) writers[b].push_back(static_cast<std::uint32_t>(t));
    }
  }

  // Store the tasks colour by colour (leaf order within a colour: the sort is stable).
  std::vector<std::size_t> order(ntasks);
  for (std::size_t t = 0; t < ntasks; ++t) order[t] = t;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t p, std::size_t q) { return colour[p] < colour[q]; });
  NearSchedule s;
  s.colour_begin.assign(1, 0);
  s.one_begin.assign(1, 0);
  s.sym_begin.assign(1, 0);
  for (std::size_t k = 0; k < ntasks; ++k) {
    const std::size_t t = order[k];
    if (k > 0 && colour[t] != colour[order[k - 1]]) s.colour_begin.push_back(k);
    const std::uint32_t l = task_leaf[t];
    s.leaf.push_back(l);
    s.one_sided.insert(s.one_sided.end(), one[l].begin(), one[l].end());
    s.one_begin.push_back(s.one_sided.size());
    s.symmetric.insert(s.symmetric.end(), sym[l].begin(), sym[l].end());
    s.sym_begin.push_back(s.symmetric.size());
  }
  if (ntasks > 0) s.colour_begin.push_back(ntasks);
  return s;
}

}  // namespace rpyfmm::rpy::detail
