// rpyfmm — the colouring of the PSE half rows (half_blocks.hpp).
#include "half_blocks.hpp"

#include <utility>

namespace rpyfmm::rpy::pse::detail {

namespace {

/// The first layer of every block along an axis of `layers` cells, and the end: >= 4 layers are
/// cut into an even number of blocks, each >= 2 layers wide; an axis of 3 layers stays whole.
std::vector<int> axis_blocks(int layers) {
  if (layers < 4) return std::vector<int>{0, layers};
  int count = layers / 2;
  if (count % 2 == 1) --count;  // even, >= 2; widths layers / count >= 2
  std::vector<int> start(static_cast<std::size_t>(count) + 1);
  for (int k = 0; k <= count; ++k) start[static_cast<std::size_t>(k)] = k * layers / count;
  return start;
}

}  // namespace

void plan_half_blocks(const std::array<int, 3>& nc, const std::vector<std::size_t>& cell_begin, HalfBlocks& out) {
  // Slot s writes to the slots t > s of the 27 cells around it, i.e. to cells of larger id:
  // layer x + 1 (any y, z), or x with y + 1 (any z), or x, y with z + 1; by the periodic wrap
  // also the last layer from the first one along each axis (x = nc_x - 1 from x = 0, and so
  // on). A block of layers [a, b) along x or y thus writes within [a, b] along x and within
  // [a - 1, b] along y (cyclically): it reaches only the first layer of the next block and the
  // last layer of the previous one. A block's colour is its parity along the cut axes: two
  // blocks of one colour are then at least one block apart along a cut axis, where their
  // footprints miss each other. z is not cut: a block then sweeps whole cell columns in slot
  // order, which keeps the neighbours' rows in cache (cutting z too, for more blocks a colour,
  // made the product 1.2-1.3x slower).
  for (auto& colour : out) colour.clear();
  const auto xs = axis_blocks(nc[0]), ys = axis_blocks(nc[1]);
  const auto ny = static_cast<std::size_t>(nc[1]), nz = static_cast<std::size_t>(nc[2]);
  for (std::size_t i = 0; i + 1 < xs.size(); ++i)
    for (std::size_t j = 0; j + 1 < ys.size(); ++j) {
      // The cells (x, y0 ... y1 - 1, all z) are consecutive ids: one slot range per x layer.
      std::vector<SlotRange> block;
      for (int x = xs[i]; x < xs[i + 1]; ++x) {
        const std::size_t first = cell_begin[(static_cast<std::size_t>(x) * ny + static_cast<std::size_t>(ys[j])) * nz];
        const std::size_t last =
            cell_begin[(static_cast<std::size_t>(x) * ny + static_cast<std::size_t>(ys[j + 1])) * nz];
        if (last > first) block.push_back({first, last});
      }
      if (!block.empty()) out[2 * (i % 2) + (j % 2)].push_back(std::move(block));
    }
}

}  // namespace rpyfmm::rpy::pse::detail
