// rpyfmm — the portable rows of the PSE real-space product: one row of M_r F / M0 without the
// self term, u += sum_q [F (I - ee) + G ee] f_q over a particle's neighbour slots nb[0..count)
// ([PSE] eq. 10 with App. A; docs/theory/pse.md). The table rows run through simd_dispatch
// (compiled per instruction-set level); the closed forms are the reference the table is measured
// against. Private.
#pragma once

#include <cstddef>

namespace rpyfmm::rpy::pse::detail {

/// Positions and forces by slot, one array per axis.
struct SlotArrays {
  const double* x[3];
  const double* f[3];
};

/// The row-layout pair cache of the portable rows: per row entry q, F - F(0), G - G(0), e_x,
/// e_y, e_z in five arrays of `stride` values each.
template <class T>
struct RowCache {
  T* data;
  std::size_t stride;
};

/// The row of a particle at xi with F, G from the linear table (table: PseRealSpaceTable::data(),
/// inv_dr: 1 / its spacing), minimum image in the box L (inv_L = 1 / L).
void table_row(const int* nb, std::size_t count, const double xi[3], const SlotArrays& s, const double* table,
               double inv_dr, const double L[3], const double inv_L[3], double u[3]);

/// table_row that also keeps each pair's values in the row cache (entries from `first` on),
/// rounded to the cache's precision, and sums the kept values (as every later product does).
/// T: float or double.
template <class T>
void fill_row(const int* nb, std::size_t count, const double xi[3], const SlotArrays& s, const double* table,
              double inv_dr, const double L[3], const double inv_L[3], RowCache<T> c, std::size_t first, double u[3]);

/// The row from the filled row cache: the forces of the neighbours and the kept values only.
template <class T>
void cached_row(const int* nb, std::size_t count, const SlotArrays& s, const double* table, RowCache<T> c,
                std::size_t first, double u[3]);

/// The row with F, G from the closed forms (real_space_fg) per pair; a coincident neighbour gets
/// the block F(0) I = self I (F(0) = G(0)).
void closed_form_row(const int* nb, std::size_t count, const double xi[3], const SlotArrays& s, const double L[3],
                     const double inv_L[3], double self, double xi_ewald, double radius, double u[3]);

}  // namespace rpyfmm::rpy::pse::detail
