// rpyfmm — the 3D Hilbert key of a cell of the 2^21 grid (partition.hpp, docs/mpi.md
// "Space-filling-curve partition").
//
// Butz's algorithm (A. R. Butz, "Alternative algorithm for Hilbert's space-filling curve", IEEE
// Trans. Comput. C-20 (1971) 424) in the formulation of C. H. Hamilton ("Compact Hilbert indices",
// Tech. Rep. CS-2006-07, Dalhousie University, 2006, Sec. 2, its Hilbert index algorithm): the key
// is built one level at a time from the coarsest. At each level the octant of the cell (one bit per
// axis) is mapped into the frame of the current subcurve (a reflection by its entry corner e and a
// rotation by its direction d, T_(e,d)), and the position of that octant along the subcurve's
// Gray-code order is the level's 3-bit digit; e and d then move to the chosen octant's subcurve.
// The digit of a level depends only on the coarser levels' bits and its own, and within a frame the
// octant-to-digit map is a bijection, so the first 3l bits of a key are exactly the cell of level
// l.
#include <cstdint>

#include "rpyfmm/mpi/partition.hpp"

namespace rpyfmm::mpi {
namespace {

constexpr unsigned kDims = 3;
constexpr unsigned kMask = (1u << kDims) - 1;

// Rotations of a 3-bit word.
unsigned rotate_right(unsigned b, unsigned k) {
  k %= kDims;
  return ((b >> k) | (b << (kDims - k))) & kMask;
}
unsigned rotate_left(unsigned b, unsigned k) {
  k %= kDims;
  return ((b << k) | (b >> (kDims - k))) & kMask;
}

unsigned gray(unsigned i) {
  return i ^ (i >> 1);
}
unsigned gray_inverse(unsigned g) {
  unsigned i = g;
  for (unsigned shift = 1; shift < kDims; ++shift) i ^= g >> shift;
  return i;
}

// The number of trailing one bits of i (Hamilton's g(i)).
unsigned trailing_ones(unsigned i) {
  unsigned n = 0;
  while ((i & 1u) != 0) ++n, i >>= 1;
  return n;
}

// The entry corner e(w) of the w-th subcube along the curve (Hamilton, Sec. 2).
unsigned entry(unsigned w) {
  return w == 0 ? 0 : gray(2 * ((w - 1) / 2));
}

// The direction d(w) of the w-th subcube (Hamilton, Sec. 2): the axis along which the subcurve
// leaves its entry corner, from the trailing ones of w - 1 (w even) or w (w odd).
unsigned direction(unsigned w) {
  if (w == 0) return 0;
  return (w % 2 == 0 ? trailing_ones(w - 1) : trailing_ones(w)) % kDims;
}

}  // namespace

std::uint64_t hilbert_key(std::uint32_t ix, std::uint32_t iy, std::uint32_t iz) {
  std::uint64_t key = 0;
  unsigned e = 0, d = 0;
  for (int level = kMortonBitsPerAxis - 1; level >= 0; --level) {
    // The octant at this level, x the most significant bit (as in morton_key).
    const unsigned octant = ((ix >> level) & 1u) << 2 | ((iy >> level) & 1u) << 1 | ((iz >> level) & 1u);
    const unsigned w = gray_inverse(rotate_right(octant ^ e, d + 1));  // T_(e,d), then the Gray-code rank
    e ^= rotate_left(entry(w), d + 1);
    d = (d + direction(w) + 1) % kDims;
    key = key << kDims | w;
  }
  return key;
}

}  // namespace rpyfmm::mpi
