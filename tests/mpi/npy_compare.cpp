// Test helper of tests/mpi/cli_across_ranks.cmake: compares two .npy files of float64 (v1.0,
// little-endian, C order) written by `rpyfmm`, independently of the tool's own reader.
//   mpi_npy_compare A.npy B.npy BOUND
// Exit status 0 when the shapes agree and |A - B|_2 <= BOUND |A|_2, 1 otherwise (with the measured
// relative difference on stdout either way), 2 when a file cannot be read.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

namespace {

struct Npy {
  std::string shape;
  std::vector<double> data;
};

bool read_npy(const char* path, Npy& a) {
  std::ifstream in(path, std::ios::binary);
  char magic[10];
  if (!in.read(magic, 10) || std::memcmp(magic, "\x93NUMPY\x01\x00", 8) != 0) return false;
  const std::size_t len = static_cast<unsigned char>(magic[8]) | (static_cast<unsigned char>(magic[9]) << 8);
  std::string header(len, '\0');
  if (!in.read(header.data(), static_cast<std::streamsize>(len))) return false;
  if (header.find("'<f8'") == std::string::npos || header.find("False") == std::string::npos) return false;
  const auto open = header.find('('), close = header.find(')');
  if (open == std::string::npos || close == std::string::npos) return false;
  a.shape = header.substr(open, close - open + 1);
  const std::streampos start = in.tellg();
  in.seekg(0, std::ios::end);
  const auto bytes = static_cast<std::size_t>(in.tellg() - start);
  in.seekg(start);
  a.data.resize(bytes / sizeof(double));
  return static_cast<bool>(in.read(reinterpret_cast<char*>(a.data.data()), static_cast<std::streamsize>(bytes)));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: mpi_npy_compare A.npy B.npy BOUND\n");
    return 2;
  }
  Npy a, b;
  if (!read_npy(argv[1], a) || !read_npy(argv[2], b)) {
    std::fprintf(stderr, "mpi_npy_compare: cannot read %s or %s as float64 .npy\n", argv[1], argv[2]);
    return 2;
  }
  if (a.shape != b.shape || a.data.size() != b.data.size()) {
    std::printf("shapes differ: %s and %s\n", a.shape.c_str(), b.shape.c_str());
    return 1;
  }
  double diff = 0.0, norm = 0.0;
  for (std::size_t i = 0; i < a.data.size(); ++i) {
    diff += (a.data[i] - b.data[i]) * (a.data[i] - b.data[i]);
    norm += a.data[i] * a.data[i];
  }
  const double relative = std::sqrt(diff / norm);
  std::printf("relative difference %.3e (bound %s)\n", relative, argv[3]);
  return relative <= std::strtod(argv[3], nullptr) ? 0 : 1;
}
