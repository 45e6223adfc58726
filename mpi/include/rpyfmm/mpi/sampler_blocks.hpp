// rpyfmm — the block preconditioner's blocks that the samplers across ranks (sqrt.hpp) built for
// an operator's positions, kept by the operator from one sampler call to the next (docs/mpi.md,
// "Brownian displacements").
#pragma once

#include <memory>
#include <utility>

namespace rpyfmm::mpi {

namespace detail {
class GlobalBlocks;          // mpi/src/global_blocks.hpp
struct SamplerBlocksWriter;  // mpi/src/sqrt.cpp: the samplers' replacement of the kept blocks
}  // namespace detail

/// The blocks of the last block-preconditioned sampler call on an operator, for its current
/// positions. The operator empties it at the start of every set_positions (so also when that call
/// fails); the samplers read it and replace it (mpi::sqrt_apply, mpi::sqrt_apply_rotation), and
/// nothing else can: the operators hand out only a const reference. Copies of an operator share the
/// blocks built before the copy, which are those of the positions both hold until a set_positions
/// empties one's own.
class SamplerBlocks {
 public:
  void clear() noexcept { blocks_.reset(); }
  [[nodiscard]] const std::shared_ptr<const detail::GlobalBlocks>& get() const noexcept { return blocks_; }

 private:
  friend struct detail::SamplerBlocksWriter;
  // Mutable because the samplers take the operator as const: the blocks are a cache of its
  // positions, derived from them, not part of its configuration.
  mutable std::shared_ptr<const detail::GlobalBlocks> blocks_;
};

}  // namespace rpyfmm::mpi
