// rpyfmm::bd — run output: extended-XYZ trajectories (OVITO, VMD, ASE) and a
// CSV log, both appended and flushed per record.
//
// Crash guarantee: each record is written whole and flushed; every checkpoint
// (written atomically) stores the byte length and a hash of the content of both
// files at that state, and a restart checks the hash and truncates them back to
// the length. So after any crash the files plus the last checkpoint form a
// consistent prefix of the run, a partially written last frame is dropped on
// restart, and a file another run wrote is refused, never cut.
//
// A new run writes each file to a temporary next to it (rpyfmm/core/file_safety.hpp)
// and publishes it (rename over the name) once the run has started; a run refused
// before that leaves nothing behind and the previous file untouched.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/core/file_safety.hpp"
#include "rpyfmm/rpy/geometry.hpp"

namespace rpyfmm::bd {

/// An append-only file, written unbuffered record by record, that knows its length and
/// the hash (Fnv1a) of everything in it. Closing it (destructor) removes an unpublished
/// temporary.
class AppendFile {
 public:
  AppendFile() = default;
  AppendFile(const AppendFile&) = delete;
  AppendFile& operator=(const AppendFile&) = delete;
  ~AppendFile();

  /// Starts a new, empty file for `path`: records go to a temporary next to it until
  /// publish(). Throws io_error if `path` exists and is not a regular file.
  void create(const std::filesystem::path& path);
  /// Reopens the regular file `path` written by an earlier run: its first keep_bytes bytes
  /// must hash to `expected_hash` (else io_error naming the file: it belongs to another
  /// run). The rest (written after the checkpoint) is cut off by publish().
  void reopen(const std::filesystem::path& path, std::uint64_t keep_bytes, std::uint64_t expected_hash);
  /// Makes the file the run's output: renames the temporary of create() over the path, or
  /// cuts a reopened file back to the checkpoint. Nothing on disk changes before; later
  /// calls do nothing.
  void publish();
  void write(const std::string& record);  ///< appends, straight to the file

  [[nodiscard]] std::uint64_t bytes() const { return bytes_; }
  [[nodiscard]] std::uint64_t hash() const { return hash_.value(); }
  [[nodiscard]] bool is_open() const { return fd_ >= 0; }
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_, temporary_;  // temporary_: empty once published
  int fd_ = -1;
  bool cut_pending_ = false;  // reopened, tail not yet cut
  std::uint64_t bytes_ = 0;
  Fnv1a hash_;
};

/// One extended-XYZ frame: species = type name, pos, radius; Time and Step in the
/// comment line; periodic boxes give Lattice and wrapped positions. With `orientations` (4N
/// quaternions w x y z; empty: none) a column orientation:R:4 follows, written x y z w: the
/// order of OVITO's Orientation property (components X, Y, Z, W), which its extended-XYZ reader
/// maps the column `orientation` to. With `complex_ids` (N entries; empty: none) a last column
/// complex:I:1 gives each particle's complex in the SAC scheme (sac.hpp): its carrier's index, or
/// -1 for a particle in no complex (Complexes::kFree).
std::string xyz_frame(std::span<const double> positions, std::span<const std::uint32_t> types,
                      const std::vector<ParticleType>& type_table, const rpy::Geometry& geometry, std::uint64_t step,
                      double time, std::span<const double> orientations = {},
                      std::span<const std::uint32_t> complex_ids = {});

/// Columns of the CSV log (header line); with split displacements two more columns:
/// the rms per particle and step of M F dt and of sqrt(2 kT dt) M^{1/2} z over the interval;
/// with rotation two more: rotational_msd, the mean of |sum of the rotation vectors since step
/// 0|^2 (4 D_r t for free spheres), and orientation_correlation, the mean of u(t) . u(0) for
/// the body z axis u (exp(-2 D_r t) for free spheres; docs/theory/bd.md Sec. 7); with Langevin
/// particles one more: langevin_kT, the mean of m |v|^2 / 3 over them (kT at equilibrium, Sec. 8);
/// with the SAC scheme two more: complexes, the number of carriers with adsorbed particles, and
/// mean_adsorbed, the mean number of adsorbed particles per complex (Sec. 9).
std::string csv_log_header(bool split_displacements = false, bool rotation = false, bool langevin = false,
                           bool sac = false);

/// The sums behind the log's rotation columns over the particles given (orientations and those at
/// step 0: 4 values each, w x y z; rotation vectors summed since step 0: 3 each): sum_i |phi_i|^2
/// and sum_i u_i(t) . u_i(0), u the body z axis (docs/theory/bd.md Sec. 7), in particle order.
/// Divided by N they are the columns; a distributed run sums them over its ranks' shares.
std::array<double, 2> rotation_moment_sums(std::span<const double> orientations, std::span<const double> reference,
                                           std::span<const double> rotation_vectors);

}  // namespace rpyfmm::bd
