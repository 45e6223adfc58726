// rpyfmm::bd — one BD frame in HOOMD-blue's GSD schema: the named data chunks a GSD trajectory
// stores per frame (schema "hoomd", version 1.4: the "HOOMD schema" page of the gsd docs).
//
// Chunks, every frame: configuration/step (uint64), configuration/box (float32 x 6: Lx Ly Lz xy
// xz yz), particles/N (uint32), particles/position (float32 N x 3), with rotation
// particles/orientation (float32 N x 4, the unit quaternion w x y z: HOOMD's (real, i, j, k)
// order, the order of bd/quaternion.hpp), in a periodic box particles/image (int32 N x 3), and
// log/bd/time (float64). Frame 0 also carries what never changes: configuration/dimensions (3),
// particles/types (int8 NT x M, NUL-padded names), particles/typeid (uint32 N) and
// particles/diameter (float32 N, twice the type's radius); readers take those of later frames
// from frame 0, as the schema specifies.
//
// Boxes. HOOMD's box is centred on the origin. Periodic: the run's box; positions are wrapped
// into [-L/2, L/2) and particles/image holds the periodic images, so position + image * L is the
// unwrapped position (to float32 rounding). Free space has no box: the frame's box is the
// origin-centred box of twice the extent of the spheres, L_d = 4 max_i (|x_id| + a_i), so the
// minimum-image separation of every pair is its true separation (|dx_d| <= L_d / 2) and a reader
// that treats the box as periodic still measures distances correctly. Positions are not moved.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/rpy/geometry.hpp"

namespace rpyfmm::bd {

/// Element types of GSD chunks: the values of gsd.h's enum gsd_type.
enum class GsdType : std::uint8_t {
  uint8 = 1,
  uint16,
  uint32,
  uint64,
  int8,
  int16,
  int32,
  int64,
  float32,
  float64,
  character
};

/// One GSD data chunk: `rows` x `columns` values of `type`, row-major, in host byte order.
struct GsdChunk {
  std::string name;
  GsdType type = GsdType::uint8;
  std::uint64_t rows = 0;
  std::uint32_t columns = 0;
  std::vector<std::byte> data;
};

/// The chunks of one frame (header comment), in the order the schema lists them. `first`: frame
/// 0 of the file, which adds the chunks that never change. `orientations`: 4N quaternions w x y
/// z, or empty without rotation.
std::vector<GsdChunk> hoomd_frame(std::span<const double> positions, std::span<const std::uint32_t> types,
                                  const std::vector<ParticleType>& type_table, const rpy::Geometry& geometry,
                                  std::uint64_t step, double time, std::span<const double> orientations, bool first);

}  // namespace rpyfmm::bd
