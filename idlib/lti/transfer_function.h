// Discrete transfer functions (the controllers as a lab writes them) and their
// exact conversion to state space.  Numerics only; the JSON form is
// formats/io/model_json.h ("type": "transfer_function"), docs/formats.md.
//
// Conventions (MATLAB's):
//   TfVariable::kZ          num, den in DESCENDING powers of z (tf(num, den, Ts)):
//                           H(z) = (n_0 z^p + ... + n_p) / (d_0 z^q + ... + d_q);
//                           num and den are right-aligned (their last entries are
//                           the constant terms).
//   TfVariable::kZInverse   num, den in ASCENDING powers of z^-1 (filt(num, den, Ts)):
//                           H = (b_0 + b_1 z^-1 + ...) / (a_0 + a_1 z^-1 + ...);
//                           left-aligned (first entries are the z^0 terms).
//   zeros/poles/gain, kZ    H(z) = k Π(z − z_i) / Π(z − p_i)            (zpk(z, p, k, Ts))
//   zeros/poles/gain, kZInverse
//                           H = k Π(1 − z_i z^-1) / Π(1 − p_i z^-1)
//                             = k z^(np−nz) Π(z − z_i) / Π(z − p_i)
//
// Realisations (all exact in the sense: no fitting, no reduction; round-off only):
//   num/den   observer canonical form of order n (n = degree of the denominator in
//             z, resp. the longer of the z^-1 polynomials less one, after removing
//             trailing zeros), after dividing by the leading denominator
//             coefficient:  A(i,0) = −a_{i+1}, A(i,i+1) = 1,  B(i) = b_{i+1} − a_{i+1} b_0,
//             C = e_1ᵀ, D = b_0; then diagonally scaled by powers of two (exact in
//             floating point) to balance the rows and columns of A.
//   zpk       a cascade (idlib/lti/interconnect.h series) of first- and
//             second-order sections, each realised as above: complex pole pairs
//             and pairs of real poles (sorted by |p|, largest first) form the
//             sections; each takes the remaining zero pair nearest its poles; the
//             gain k multiplies the last section's numerator.  Keeps notches and
//             lightly damped poles well conditioned.
//   matrix    each non-zero element realised on its own and stacked block-diagonally
//             (A = blkdiag(A_ij), B_ij feeds from input j, C_ij to output i, D = [D_ij]):
//             exact but NOT minimal (order = sum of element orders; a column of
//             elements sharing a denominator is not merged).
//
// Every function throws InputError (message = what, and the fix; the caller adds
// the place in the file) for: an empty denominator, a denominator whose leading
// coefficient (kZ: of the highest power of z; kZInverse: of z^0) is zero, an
// improper element (more zeros than poles in z), a complex zero or pole without
// its conjugate (relative tolerance kConjugateRelTolerance), non-finite values,
// a sample period that is not positive.
#pragma once

#include <optional>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

enum class TfVariable { kZ, kZInverse };

// One SISO element, either form.
struct SisoTf {
  bool is_zpk = false;
  std::vector<double> num, den;         // !is_zpk: coefficients in the order of `variable`
  std::vector<Complex> zeros, poles;    // is_zpk
  double gain = 1.0;                    // is_zpk
};

// Two values are a conjugate pair when |a − conj(b)| <= this × max(|a|, |b|)
// (values copied from MATLAB are exact conjugates; typed ones agree to the digits typed).
inline constexpr double kConjugateRelTolerance = 1e-12;

// The element realised (1 input, 1 output) at sample period sample_period_s > 0.
StateSpace realize_siso(const SisoTf& tf, TfVariable variable, double sample_period_s);

// A p × m matrix of elements (row-major, entries[i * m + j] maps input j to
// output i; std::nullopt = a zero element).  Block stacking as above.
StateSpace realize_tf_matrix(const std::vector<std::optional<SisoTf>>& entries, Index outputs, Index inputs,
                             TfVariable variable, double sample_period_s);

// H(e^{jωT}) evaluated directly from the coefficients / factors (Horner's rule),
// for checks.  Same conventions and rules as realize_siso.
Complex evaluate_siso(const SisoTf& tf, TfVariable variable, double sample_period_s, double omega_rad_s);

}  // namespace lpvid
