// Model reduction: modal removal, minimal realisation, balanced truncation.
//
// | model  | shape |
// |--------|-------|
// | A      | n x n (result r x r) |
// | B      | n x m (result r x m) |
// | C      | p x n (result p x r) |
// | D      | p x m (unchanged)    |
// Sample period and names are kept.  Results are compared by invariants
// (frequency response, poles), never by their A, B, C: the state basis is not
// unique.
#pragma once

#include <Eigen/Core>

#include "idlib/core/types.h"

namespace lpvid {

// Removes `count` eigenvalues of A: those nearest (|λ − t|, in the s- or z-plane
// of the model) to any of `targets`; one target may absorb several eigenvalues.
// Complex pairs are removed together.
//
// Method: real Schur form A = U T Uᵀ, each 2x2 block split by a unitary rotation
// into a complex triangular form, reordered by adjacent unitary swaps (the
// 1x1 case of LAPACK ztrexc) so that the removed eigenvalues lead:
//   T = [[T11 T12]; [0 T22]],  U = [U1 U2].
// The Sylvester equation T11 X − X T22 = −T12 (triangular, solved by columns)
// block-diagonalises T; the kept system is
//   (T22, U2ᴴ B, C (U1 X + U2), D),
// i.e. the spectral projection onto the kept eigenvalues, returned in a real
// basis of the (conjugation-closed) kept invariant subspaces.  The transfer
// function changes by exactly the removed modal part C_1 (λI − T11)⁻¹ B_1, which
// is zero when the removed modes are uncontrollable or unobservable.
// Accuracy degrades as 1/sep(T11, T22) when removed and kept eigenvalues are
// close (inherent to any spectral splitting).
//
// @throws InputError  sys invalid; count outside [0, n]; targets empty (count > 0)
//                     or non-finite; the count-th nearest eigenvalue belongs to a
//                     complex pair whose partner would be kept (use count ± 1).
StateSpace remove_modes(const StateSpace& sys, const Eigen::VectorXcd& targets, Index count);

// Removes the uncontrollable, then the unobservable part by orthogonal staircase
// reductions (Varga, "Minimal realization procedures based on balancing and
// related techniques", 1991; the SLICOT TB01PD idea).  At each staircase step a
// direction counts as reachable (resp. observable) when its singular value
// exceeds tolerance · max(‖A‖_F, ‖B‖_F) (resp. tolerance · max(‖A‖_F, ‖C‖_F));
// tolerance is therefore relative, e.g. 1e-10 for exact models, ~ the relative
// noise level for identified ones.
// @throws InputError  sys invalid; tolerance not in (0, 1).
StateSpace minimal_realization(const StateSpace& sys, double tolerance);

// Controllability and observability Gramians P, Q of a stable model:
//   continuous:  A P + P Aᵀ + B Bᵀ = 0,   Aᵀ Q + Q A + Cᵀ C = 0
//   discrete:    A P Aᵀ − P + B Bᵀ = 0,   Aᵀ Q A − Q + Cᵀ C = 0
// solved by Bartels–Stewart on the complex Schur form (O(n³)).
struct Gramians {
  Eigen::MatrixXd controllability, observability;
};
// @throws InputError  sys invalid or not stable (is_stable).
Gramians gramians(const StateSpace& stable_sys);

// σ_i = sqrt(λ_i(P Q)), descending, computed as the singular values of L_Qᵀ L_P
// with P = L_P L_Pᵀ, Q = L_Q L_Qᵀ (symmetric square-root factors).
// @throws InputError  as gramians().
Eigen::VectorXd hankel_singular_values(const StateSpace& stable_discrete_or_continuous);

// Square-root balanced truncation (Laub et al. 1987) to `order` states:
// keeps the `order` largest Hankel singular values; the H∞ error is at most
// 2 Σ_{i>order} σ_i.
// @throws InputError  as gramians(); order outside [0, n]; σ_order == 0
//                     (the model has fewer than `order` reachable-and-observable
//                     states: reduce to the minimal order instead).
StateSpace balanced_truncation(const StateSpace& stable_sys, Index order);

}  // namespace lpvid
