// npy_fixture IN OUT KIND — writes the array read from IN (text or .npy) as the .npy file OUT for
// the collective-I/O tests of the command-line tool across ranks (tests/mpi/cli_across_ranks.cmake):
//   f8        float64, C order (the serial writer's file);
//   f4        float32, C order (values rounded to float);
//   i4        the float64 file with its header's dtype replaced by '<i4' (unsupported);
//   short     the float64 file without its last value (a short file);
//   nan:K     the float64 file with value K (flat index) replaced by NaN.
// Exits 0 on success, 2 with a message otherwise.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <fstream>
#include <iostream>
#include <limits>
#include <string>
#include <vector>

#include "array_io.hpp"

namespace {

using rpyfmm::cli::Array;

// The header of `a` with `descr` in place of '<f8' (three characters: the padding is unchanged).
std::string header_with(const Array& a, const std::string& descr) {
  std::string header = rpyfmm::cli::npy_header(a.shape);
  header.replace(header.find("<f8"), 3, descr);
  return header;
}

void write_bytes(const std::string& path, const std::string& header, const char* data, std::size_t bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(header.data(), static_cast<std::streamsize>(header.size()));
  out.write(data, static_cast<std::streamsize>(bytes));
  if (!out) throw std::runtime_error("cannot write " + path);
}

void write_kind(Array a, const std::string& out, const std::string& kind) {
  const char* f8 = reinterpret_cast<const char*>(a.data.data());
  const std::size_t bytes = a.data.size() * sizeof(double);
  if (kind == "f8" || kind == "i4") {
    write_bytes(out, header_with(a, kind == "f8" ? "<f8" : "<i4"), f8, bytes);
  } else if (kind == "f4") {
    const std::vector<float> narrow(a.data.begin(), a.data.end());
    write_bytes(out, header_with(a, "<f4"), reinterpret_cast<const char*>(narrow.data()), 4 * narrow.size());
  } else if (kind == "short") {
    write_bytes(out, header_with(a, "<f8"), f8, bytes - sizeof(double));
  } else if (kind.rfind("nan:", 0) == 0) {
    a.data.at(std::stoul(kind.substr(4))) = std::numeric_limits<double>::quiet_NaN();
    write_bytes(out, header_with(a, "<f8"), reinterpret_cast<const char*>(a.data.data()), bytes);
  } else {
    throw std::runtime_error("unknown kind '" + kind + "'");
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::cerr << "usage: npy_fixture IN OUT f8|f4|i4|short|nan:K\n";
    return 2;
  }
  try {
    write_kind(rpyfmm::cli::read_array(argv[1]), argv[2], argv[3]);
  } catch (const std::exception& e) {
    std::cerr << "npy_fixture: " << e.what() << '\n';
    return 2;
  }
  return 0;
}
