// lpvid — Ho-Kalman / Eigensystem Realization Algorithm (ERA) with scaled
// channels, a strided block Hankel matrix and automatic order selection.
//
// Reference: Ho & Kalman (1966); Juang & Pappa (1985), ERA; Gajdušek et al.
// (seed 000) eqs 10-13.  The seed's eq (13) prints B = U_n Sigma_n^1/2 and
// C = Sigma_n^1/2 V_n^T: swapped, and not cut to a block column / row
// (DESIGN.md, math item 2).  This file implements the correct formulas below.
//
// Data layout: idlib/core/types.h (g[k] is outputs x inputs at lag k).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/core/types.h"

namespace lpvid {

struct EraOptions {
  double sample_period_s = 0;  // required > 0; copied into the model
  Index order = 0;             // 0 = choose automatically (see realize_era)
  Index max_order = 40;        // largest order the automatic rule may choose
  // More orders to realise from the same SVD (EraResult::models_at), e.g. starting
  // models at several orders for one Hankel matrix.  Each must be 1..max_order and at
  // most the Hankel matrix's dimension; orders the matrix cannot hold get an empty model.
  std::vector<Index> also_orders;
  // Hankel layout (hankel.h): 0 = choose from the data (see realize_era).
  Index block_rows = 0, block_cols = 0, stride = 0;
  Eigen::VectorXd input_scale;       // m: spread (RMS) of each excitation; empty = derive from g
  Eigen::VectorXd output_scale;      // p: spread of each output; empty = derive from g
  Eigen::MatrixXd markov_noise_std;  // p x m standard error of each g entry; empty = estimate from the tail of g
  bool estimate_feedthrough = true;  // D = g[0]; false: D = 0
  // With stride d > 1, build the Hankel matrix from sums of d consecutive lags
  // (realize_era, step 5a): sqrt(d) less noise; false: plain strided lags.
  bool sum_stride_lags = true;
  std::vector<std::string> input_names, output_names;  // copied into the model

  // Checks what can be checked without g (sample period, counts, signs, finite
  // scales and noise levels).  @throws InputError naming the field and the rule.
  void validate() const;
};

struct OrderSelection {
  Index order = 0;
  std::string rule;                 // "given" or "noise-floor"
  std::string reason;               // one sentence a user can read: why this order
  Eigen::VectorXd singular_values;  // leading Hankel singular values (scaled channels), descending
  double noise_floor = 0;           // singular-value level of the noise alone (scaled channels)
  double threshold = 0;             // values above it count as dynamics
};

struct EraResult {
  StateSpace model;  // discrete, sample_period_s as given, ORIGINAL (unscaled) units
  OrderSelection selection;
  Index block_rows = 0, block_cols = 0, stride = 1;
  Index effective_length = 0;  // last lag (+1) where the response stands above the noise
  Eigen::VectorXd input_scale, output_scale;  // as used (given or derived)
  Eigen::MatrixXd markov_noise_std;           // p x m, as used (given or estimated), original units
  Report report;                              // warnings: unstable model, order at max_order, ...
  // One per EraOptions::also_orders, same order (order 0: the Hankel matrix cannot hold it).
  std::vector<StateSpace> models_at;
};

// Realises a discrete state-space model x[k+1] = A x[k] + B u[k], y = C x + D u
// with g[k] = C A^(k-1) B (k >= 1), g[0] = D, from Markov parameters.
//
// | argument / result | shape |
// |-------------------|-------|
// | g[k]              | p x m, k = 0..L |
// | input_scale       | m (or empty) |
// | output_scale      | p (or empty) |
// | markov_noise_std  | p x m (or empty) |
// | model.A           | n x n |
// | model.B           | n x m |
// | model.C           | p x n |
// | model.D           | p x m |
//
// Steps:
// 1. Scaling.  g~[k](i,j) = g[k](i,j) * input_scale(j) / output_scale(i), so that
//    a channel in small units (metres beside radians) does not fall under the
//    noise of the others.  When not given, the scales balance the channels:
//    output_scale(i) and 1/input_scale(j) are the RMS of row i / column j of
//    g[1..L] (three alternating passes); the noise std scales with g.
// 2. Noise level.  markov_noise_std, or when empty, per entry from the last
//    quarter of the lags (at least 16 of them): 1.4826 * MAD of the first
//    differences / sqrt(2) (differences remove a slowly decaying remainder of
//    the response).
// 3. Effective length L_eff: K + 1 for the largest K whose tail g~[K..L] carries
//    more energy than N noise blocks (N = L - K + 1, each of expected energy
//    s2 = max(sum_ij std~(i,j)^2, mean energy of the last quarter of g~)) by
//    more than 5 s2 sqrt(2N) (5 standard deviations); a slow weak mode is found
//    through its accumulated energy.  Noise-free: energy above (1e-9)^2 of the
//    peak ||g~[k]||_F^2 per lag.
// 4. Hankel layout (each 0 field chosen here, first lag = 1):
//      block_rows = max(ceil(600 / p), ceil(k_max / p)),  block_cols alike with m,
//      k_max = max(order, max_order) + 1 singular values needed,
//    shrunk to fit L_eff when the response is shorter (d = 1), then
//      stride d = max(1, ceil((L_eff - 1) / (block_rows + block_cols - 1))),
//    lowered so that the shifted Hankel fits in g: 1 + (rows + cols - 1) d <= L
//    (2 + (rows + cols - 2) d <= L without sums).
//    The 600-row target keeps the partial SVD near 50 ms and gives 200 blocks to
//    a 3x3 system, far more than the 2r x 2r of python-control, which noise needs.
// 5. H = block_hankel(g~, rows, cols, 1, d) = U S V^T, leading k_max triplets
//    (leading_svd).  Order n (below).  Then, with U_n, S_n, V_n:
//      O = U_n S_n^1/2,   R = S_n^1/2 V_n^T,
//      C~ = first p rows of O,   B~ = first m columns of R,
//      A  = S_n^-1/2 U_n^T H1 V_n S_n^-1/2,  H1 = block_hankel(g~, rows, cols, 2, d)
//    (H1 is shifted by ONE sample, so A is at the original sample rate whatever
//    the stride: H1(i,j) = C A^id A A^jd B).
// 5a. With d > 1 and sum_stride_lags (default), g~ is first replaced by
//    h[k] = sum_{l<d} g~[k+l] = C A^(k-1) B_d, B_d = S B, S = sum_{l<d} A^l:
//    a moving-sum anti-alias filter that uses every lag instead of one in d.
//    Entries d apart share no lag, so the noise stays white with std sqrt(d)
//    times larger while slow dynamics grow d times.  The same formulas give A,
//    C and B_d; then B = S^-1 B_d.  A mode at a multiple of fs/d (sum zero) is
//    hidden; the report warns when S is near singular.  g must then hold lags
//    up to 1 + (rows + cols - 1) d.
// 6. Unscaling: B = B~ diag(1 / input_scale), C = diag(output_scale) C~,
//    D = g[0] (or 0).
//
// Automatic order (rule "noise-floor"):
//   nu = largest singular value of a Hankel matrix of the same layout filled
//        with white Gaussian noise of the per-entry std~ (computed, fixed seed;
//        a random Hankel matrix's norm exceeds the i.i.d.-matrix value
//        std (sqrt(rows) + sqrt(cols)) by a log factor, so it is not guessed);
//   threshold = max(kappa * nu, 1e-10 * s_1), kappa = 3: the (n+1)-th singular
//        value of signal + noise is at most ||noise|| (Weyl), so kappa leaves a
//        factor 3 for a misjudged noise level; 1e-10 is the rank tolerance of
//        noise-free data;
//   n = number of singular values above the threshold, at most max_order.
//   All values above the noise are kept: a plain largest-gap rule picks the gap
//   between strong and weak modes (6 plant + 3 weak controller modes of a closed
//   loop) or a random gap in the noise.  The reason names the count, the floor,
//   kappa and the ratio s_n / s_(n+1) at the chosen boundary.
//
// Report warnings: the model has a pole with |z| >= 1; the order reached
// max_order; the chosen boundary ratio s_n / s_(n+1) is below 2 (order
// uncertain); a given order keeps singular values below the noise threshold.
//
// @throws InputError  options.validate(); g empty, of mixed shapes, or non-finite;
//                     scales / noise std / names not matching p and m; g too short
//                     for the Hankel layout (the message says the minimum number
//                     of lags); order greater than the Hankel matrix allows.
// @throws NumericalError  automatic order and no singular value stands above the
//                     noise floor.
EraResult realize_era(const MarkovSequence& g, const EraOptions& options);

}  // namespace lpvid
