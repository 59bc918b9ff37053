// Weighted relative error between two frequency responses (layout:
// idlib/core/types.h, responses indexed (output, input, frequency)).
//
//   e(ω) = ‖W_l (P̂(ω) − P(ω)) W_r‖₂ / ‖W_l P(ω) W_r‖₂,
//   W_l = diag(left_weight), W_r = diag(right_weight),  ‖·‖₂ = largest singular value.
//
// | argument     | shape |
// |--------------|-------|
// | estimate     | p x m complex (per frequency) |
// | truth        | p x m complex (per frequency) |
// | left_weight  | p, or empty (= ones) |
// | right_weight | m, or empty (= ones) |
// | omega_rad_s  | F, rad/s |
//
// Weights scale the channels (e.g. 1/range of each output, or to make rad and m
// comparable); they must be finite and >= 0.  The error is dimensionless.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

// @throws InputError  shapes differ or do not match the weights; a weight is
//                     negative or non-finite; an entry is non-finite; the
//                     weighted truth is zero (the relative error is undefined).
double weighted_matrix_error(const Eigen::MatrixXcd& estimate, const Eigen::MatrixXcd& truth,
                             const Eigen::VectorXd& left_weight, const Eigen::VectorXd& right_weight);

struct ErrorSummary {
  double mean = 0, max = 0;        // over frequency (plain arithmetic mean)
  double omega_at_max_rad_s = 0;   // the first frequency where max occurs
  Eigen::VectorXd per_frequency;   // e(ω_k), F entries
};

// e(ω_k) for every frequency, with mean and max.
// @throws InputError  as weighted_matrix_error (the message names the frequency);
//                     estimate, truth and omega_rad_s differ in length, or are empty.
ErrorSummary weighted_error_over(const std::vector<Eigen::MatrixXcd>& estimate, const std::vector<Eigen::MatrixXcd>& truth,
                                 const Eigen::VectorXd& omega_rad_s, const Eigen::VectorXd& left_weight,
                                 const Eigen::VectorXd& right_weight);

}  // namespace lpvid
