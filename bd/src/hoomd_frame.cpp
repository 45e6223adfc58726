#include "rpyfmm/bd/hoomd_frame.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

namespace rpyfmm::bd {

namespace {

/// A chunk of `rows` x `columns` values copied from `values` (rows * columns of them).
template <class T>
GsdChunk chunk(const char* name, GsdType type, std::uint64_t rows, std::uint32_t columns,
               const std::vector<T>& values) {
  GsdChunk c{name, type, rows, columns, std::vector<std::byte>(values.size() * sizeof(T))};
  if (!values.empty()) std::memcpy(c.data.data(), values.data(), c.data.size());
  return c;
}

/// particles/types: the names as NUL-padded rows of int8, one more column than the longest.
GsdChunk type_names(const std::vector<ParticleType>& table) {
  std::size_t width = 1;
  for (const auto& t : table) width = std::max(width, t.name.size() + 1);
  std::vector<char> names(table.size() * width, '\0');
  for (std::size_t k = 0; k < table.size(); ++k)
    std::copy(table[k].name.begin(), table[k].name.end(), names.begin() + static_cast<std::ptrdiff_t>(k * width));
  return chunk("particles/types", GsdType::int8, table.size(), static_cast<std::uint32_t>(width), names);
}

/// The free-space box: four times the largest |x_id| + a_i per axis (hoomd_frame.hpp).
std::array<float, 6> open_box(std::span<const double> x, std::span<const std::uint32_t> types,
                              const std::vector<ParticleType>& table) {
  std::array<double, 3> reach{0, 0, 0};
  for (std::size_t i = 0; i < types.size(); ++i)
    for (int d = 0; d < 3; ++d) reach[d] = std::max(reach[d], std::abs(x[3 * i + d]) + table[types[i]].radius);
  return {
      static_cast<float>(4 * reach[0]), static_cast<float>(4 * reach[1]), static_cast<float>(4 * reach[2]), 0, 0, 0};
}

/// Periodic positions wrapped into [-L/2, L/2) in float32, and their images (x = p + n L).
void wrap(std::span<const double> x, const std::array<double, 3>& box, std::vector<float>& position,
          std::vector<std::int32_t>& image) {
  for (std::size_t k = 0; k < x.size(); ++k) {
    const double L = box[k % 3];
    double n = std::floor(x[k] / L + 0.5);
    auto p = static_cast<float>(x[k] - n * L);
    if (p >= static_cast<float>(L / 2)) {  // rounding can reach the upper face: use the lower one
      p = static_cast<float>(x[k] - (n + 1) * L);
      n += 1;
    } else if (p < static_cast<float>(-L / 2)) {
      p = static_cast<float>(x[k] - (n - 1) * L);
      n -= 1;
    }
    position[k] = p;
    image[k] = static_cast<std::int32_t>(n);
  }
}

/// The box chunk: the run's periodic box, or the free-space box of the frame.
GsdChunk box_chunk(std::span<const double> x, std::span<const std::uint32_t> types,
                   const std::vector<ParticleType>& table, const rpy::Geometry& geometry) {
  std::array<float, 6> box{};
  if (geometry.is_periodic()) {
    const auto& L = geometry.box();
    box = {static_cast<float>(L[0]), static_cast<float>(L[1]), static_cast<float>(L[2]), 0, 0, 0};
  } else {
    box = open_box(x, types, table);
  }
  return chunk("configuration/box", GsdType::float32, 6, 1, std::vector<float>(box.begin(), box.end()));
}

/// particles/typeid and particles/diameter (frame 0 only).
void append_types(std::vector<GsdChunk>& out, std::span<const std::uint32_t> types,
                  const std::vector<ParticleType>& table) {
  const std::uint64_t n = types.size();
  out.push_back(type_names(table));
  out.push_back(
      chunk("particles/typeid", GsdType::uint32, n, 1, std::vector<std::uint32_t>(types.begin(), types.end())));
  std::vector<float> diameter(n);
  for (std::size_t i = 0; i < n; ++i) diameter[i] = static_cast<float>(2 * table[types[i]].radius);
  out.push_back(chunk("particles/diameter", GsdType::float32, n, 1, diameter));
}

/// particles/position, and in a periodic box particles/image.
void append_positions(std::vector<GsdChunk>& out, std::span<const double> x, const rpy::Geometry& geometry) {
  const std::uint64_t n = x.size() / 3;
  std::vector<float> position(3 * n);
  if (!geometry.is_periodic()) {
    std::transform(x.begin(), x.end(), position.begin(), [](double v) { return static_cast<float>(v); });
    out.push_back(chunk("particles/position", GsdType::float32, n, 3, position));
    return;
  }
  std::vector<std::int32_t> image(3 * n);
  wrap(x, geometry.box(), position, image);
  out.push_back(chunk("particles/position", GsdType::float32, n, 3, position));
  out.push_back(chunk("particles/image", GsdType::int32, n, 3, image));
}

}  // namespace

std::vector<GsdChunk> hoomd_frame(std::span<const double> x, std::span<const std::uint32_t> types,
                                  const std::vector<ParticleType>& table, const rpy::Geometry& geometry,
                                  std::uint64_t step, double time, std::span<const double> orientations, bool first) {
  const std::uint64_t n = types.size();
  std::vector<GsdChunk> out;
  out.push_back(chunk("configuration/step", GsdType::uint64, 1, 1, std::vector<std::uint64_t>{step}));
  if (first) out.push_back(chunk("configuration/dimensions", GsdType::uint8, 1, 1, std::vector<std::uint8_t>{3}));
  out.push_back(box_chunk(x, types, table, geometry));
  out.push_back(chunk("particles/N", GsdType::uint32, 1, 1, std::vector<std::uint32_t>{static_cast<std::uint32_t>(n)}));
  if (first) append_types(out, types, table);
  append_positions(out, x.first(3 * n), geometry);
  if (!orientations.empty()) {  // w x y z: the order of bd/quaternion.hpp and of HOOMD
    std::vector<float> q(orientations.size());
    std::transform(orientations.begin(), orientations.end(), q.begin(), [](double v) { return static_cast<float>(v); });
    out.push_back(chunk("particles/orientation", GsdType::float32, n, 4, q));
  }
  out.push_back(chunk("log/bd/time", GsdType::float64, 1, 1, std::vector<double>{time}));
  return out;
}

}  // namespace rpyfmm::bd
