// Where do two frequency responses differ?  A first version of `compare`: the
// distance between a response and a reference per channel and frequency band.
//
// For channel (i, j) in a band B (a set of frequencies ω_k):
//   share_percent  = 100 · max_{k∈B} |Â_ij − R_ij| / ‖W_l R W_r‖₂ · w_l,i w_r,j
//                    (the channel's error as a share of the whole weighted matrix's
//                    gain at that frequency: small cross-couplings do not blow up)
//   gain_db        = mean_{k∈B} |20 log10 |Â_ij| − 20 log10 |R_ij||
//   phase_deg      = mean_{k∈B} |arg(Â_ij / R_ij)| in degrees
//                    (both over the frequencies where the reference channel is not
//                    negligible, see kMinChannelShare)
// and over all channels the weighted matrix error ‖W_l (Â − R) W_r‖₂/‖W_l R W_r‖₂
// (validate/frequency_error.h) per frequency, with its mean and max per band.
#pragma once

#include <string>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

struct CompareOptions {
  double band_min_rad_s = 0;       // 0: lowest frequency given
  double band_max_rad_s = 0;       // 0: highest frequency given
  double bands_per_decade = 1.0;   // bands are log-spaced between min and max
  Eigen::VectorXd left_weight;     // p (outputs); empty = ones
  Eigen::VectorXd right_weight;    // m (inputs); empty = ones
  void validate() const;           // throws InputError naming the rule
};

struct ChannelBandError {
  Index output = 0, input = 0;
  double band_lo_rad_s = 0, band_hi_rad_s = 0;
  Index points = 0;
  double share_percent = 0;  // see header comment
  double gain_db = 0;    // NaN when the channel never carries kMinChannelShare of the gain
  double phase_deg = 0;  // NaN likewise
  Index gain_points = 0; // frequencies that entered gain_db and phase_deg
};

// gain_db and phase_deg use only frequencies where |R_ij| w_i w_j is at least this
// share of ‖W R W‖₂ (0.1 %: below it the channel is numerically a zero of the reference).
inline constexpr double kMinChannelShare = 1e-3;

struct BandError {
  double band_lo_rad_s = 0, band_hi_rad_s = 0;
  Index points = 0;
  double weighted_mean = 0, weighted_max = 0;  // fractions (0.01 = 1 %)
  Index flagged = 0;                           // flagged frequencies skipped
};

struct CompareResult {
  std::vector<ChannelBandError> channels;  // every channel x band, worst share first
  std::vector<BandError> bands;            // in frequency order
  double weighted_mean = 0, weighted_max = 0, omega_at_max_rad_s = 0;  // over all used frequencies
};

// | argument  | layout |
// |-----------|--------|
// | estimate  | F matrices p x m (Â) |
// | reference | F matrices p x m (R) |
// | omega     | F, increasing, rad/s |
// | flagged   | F or empty: frequencies to skip (untrusted) |
// @throws InputError  shapes differ, no frequency in the band, bad options.
CompareResult compare_responses(const std::vector<Eigen::MatrixXcd>& estimate,
                                const std::vector<Eigen::MatrixXcd>& reference, const Eigen::VectorXd& omega_rad_s,
                                const std::vector<bool>& flagged, const CompareOptions& options);

}  // namespace lpvid
