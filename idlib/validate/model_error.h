// lpvid — the frequency-domain model-error model (Ljung, "Model validation and
// model error models", 1999; System Identification, 2nd ed., §16.6): the map
// input -> residual, E(jω) = P_data(jω) − P_model(jω), shown as a response of its
// own with a confidence region from the measurement's coherence, and the
// frequencies where E is larger than the noise of the measurement ("significant")
// grouped into failing bands with their size and a plain-words signature.
// Layout: idlib/core/types.h (responses indexed (output, input, frequency)).
//
// Noise.  The caller gives σ_c per real part of every entry (the measurement's
// own noise: idlib/fit's data_sigma() reads it from the data's variance, or from
// coherence with its number of averages, or a stated noise level).  The complex
// error Ĥ − H is then (to first order) circular with standard deviation σ_c in each
// of its real and imaginary parts, |Ĥ − H| / σ_c is Rayleigh distributed:
//
//   P(|Ĥ − H| > k σ_c) = exp(−k² / 2),   so   k = sqrt(−2 ln(1 − confidence))
//
// (k = 3.035 for 99 %).  A frequency of channel (i, j) is SIGNIFICANT when
// |E_ij| > k σ_eff,ij, σ_eff = max(σ_c, resolution · s_ij): the model differs from
// the measurement by more than its noise explains, and by more than lpvid resolves
// (`resolution`, 0.01 % of the channel's scale s_ij = max(sqrt(|Ĥ_ii| |Ĥ_jj|), |Ĥ_ij|),
// or the row's largest |Ĥ| for non-square data, floored as the fit's (response_scales,
// idlib/core/types.h): round-off of exported numbers, a
// coherence of exactly 1 and the last digits of a fit would otherwise make every
// difference on noise-free data significant; 0.01 % stays below the noise of real
// analyzer data, ~0.05–0.2 %).  σ_c = ∞ (coherence 0) makes
// nothing significant there.  Frequencies flagged in the data are skipped.
//
// Failing bands.  Per channel, over the unflagged frequencies in order: a band
// starts and ends at a significant frequency, bridges at most max_gap_points
// non-significant frequencies in a row, and is kept when it holds at least
// min_band_points significant frequencies.  A single frequency beyond k σ_c happens
// by chance with probability 1 − confidence; three in a row about (1 − c)³, so the
// minimum count keeps noise from being mistaken for a missing effect when many
// frequencies and channels are tested at once.  Kept bands of one channel closer
// than merge_decades (next lo / previous hi <= 10^merge_decades) are then joined:
// an error that grows across the threshold flickers in and out of significance
// near it, and is one failure, not several (joining kept bands adds no false ones).
//
// Size of a band (over its significant frequencies):
//   gain_db   = 20 log10 |P_data / P_model|   (mean, and the value of largest size)
//   phase_deg = arg(P_data / P_model) in deg (mean, and the value of largest size)
//   relative  = 100 |E| / |P_data| percent   (mean and max; meaningless near a zero
//               of the entry: an off-diagonal at the lowest lines read 2-3e5 %)
//   scaled    = 100 |E| / s_ij percent       (max; the error figure's scale, shown)
//   share     = the band's share of the set's squared error figure (ranks phenomena)
// gain and phase are NaN when P_model is zero somewhere in the band (below 1e-6 of
// |P_data|, i.e. −120 dB: a coupling that cancels only up to rounding).
//
// Signature (the first rule that holds; `signature` is the key, `hint` the words):
//   "coupling"      an off-diagonal channel (i ≠ j) where the model's mean |P_model|
//                   is below 30 % of the data's: "off-diagonal coupling the model
//                   lacks (model at 5 % of the measured)".
//   "narrow_peak"   |E| peaks inside the band (not at its first or last 15 %),
//                   the peak is >= 3 x |E| at both ends and the band spans less than
//                   half a decade: "narrow peak at 612 rad/s (a mode missing from
//                   the model, or placed wrongly)".
//   "delay"         phase error of one sign whose least-squares fit −ω τ leaves
//                   less than 30 % of its RMS, and the gain error explains less of
//                   |E| than the phase: "phase lag growing with frequency (like a
//                   delay of 1.0 ms)" (or "phase lead ..." when τ < 0).
//   "coupling"      any other off-diagonal band: "off-diagonal coupling error".
//   "low_frequency_gain"  gain dominates and the band starts at the lowest
//                   unflagged frequency: "low-frequency gain error (+1.6 dB):
//                   static gain or stiffness".
//   "high_frequency_gain" gain dominates and the band ends at the highest one:
//                   "high-frequency gain error (−2.0 dB): mass or inertia".
//   "gain" / "phase"      whichever of gain and phase explains more of |E|.
// ("gain dominates": |10^(gain_db/20) − 1| >= |phase in rad| at the largest |E|.)
// With several data sets, mark_differences_between_data adds "differs between data
// sets" to failures that do not appear (overlapping band, same channel) in every set.
#pragma once

#include <string>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

struct ModelErrorOptions {
  // Confidence of the band, in (0, 1): 0.99 gives k = 3.035.
  double confidence = 0.99;
  // σ_eff >= resolution · s_ij (0.01 %; see above).  >= 0.
  double resolution = 1e-4;
  // A failing band holds at least this many significant frequencies (>= 1).
  Index min_band_points = 3;
  // Non-significant frequencies in a row bridged inside a band (>= 0).
  Index max_gap_points = 1;
  // Kept bands of one channel whose gap spans at most this many decades are joined
  // (0.1 decade: 26 % in frequency; two modes closer than that read as one band).  >= 0.
  double merge_decades = 0.1;

  // @throws InputError naming the first field that breaks its rule.
  void validate() const;
};

// k = sqrt(−2 ln(1 − confidence)): the radius of the confidence circle in units of σ_c.
double confidence_radius(double confidence);

using BoolMatrix = Eigen::Matrix<bool, Eigen::Dynamic, Eigen::Dynamic>;

// The model-error model of one data set.  F = data.num_frequencies(); every
// vector has F entries of p x m matrices.
struct ModelErrorModel {
  Eigen::VectorXd omega_rad_s;             // the data's grid
  std::vector<Eigen::MatrixXcd> data;      // P_data
  std::vector<Eigen::MatrixXcd> model;     // P_model on the same grid
  std::vector<Eigen::MatrixXcd> error;     // E = P_data − P_model
  std::vector<Eigen::MatrixXd> sigma;      // σ_eff (per real part; +inf where unknown)
  std::vector<Eigen::MatrixXd> scale;      // s_ij
  std::vector<Eigen::MatrixXd> radius;     // k σ_eff: the confidence radius
  std::vector<BoolMatrix> significant;     // |E| > k σ_eff (false where skipped)
  std::vector<bool> skipped;               // flagged in the data
  double k = 0;                            // confidence_radius(options.confidence)
};

struct FailingBand {
  Index data_index = 0;              // which data set (as passed by the caller)
  Index output = 0, input = 0;       // channel, 0-based
  double lo_rad_s = 0, hi_rad_s = 0; // first and last significant frequency
  Index first = 0, last = 0;         // their indices in the data's grid
  Index points = 0;                  // significant frequencies in the band
  double gain_db_mean = 0, gain_db_max = 0;    // max = the value of largest size
  double phase_deg_mean = 0, phase_deg_max = 0;
  double relative_percent_mean = 0, relative_percent_max = 0;  // against |P_data_ij| (huge near a zero)
  // 100 max |E_ij| / s_ij: the size against the error figure's scale (unit-consistent;
  // an off-diagonal entry near zero is measured against its diagonals, not itself).
  double scaled_percent_max = 0;
  // Σ |E_ij / s_ij|² over the band's significant frequencies over the same sum over
  // every channel and unflagged frequency of the set: the band's share of the set's
  // squared error figure (docs/math.md, "Error figure"), what it matters.
  double error_share = 0;
  double omega_at_max_rad_s = 0;     // where |E| / |P_data| is largest
  double max_sigma_ratio = 0;        // max |E| / σ_c (how far beyond the noise)
  std::string signature;             // key, see the header comment
  std::string hint;                  // plain words
  bool differs_between_data = false; // set by mark_differences_between_data
};

// E, σ_eff and significance for one data set.
//
// | argument | shape |
// |----------|-------|
// | data     | F frequencies of p x m, flagged empty or F |
// | model    | F matrices p x m: the model evaluated on data.omega_rad_s |
// | sigma    | F matrices p x m: σ_c per real part (> 0, +inf allowed) |
// @throws InputError  bad options; no frequencies; model or sigma count or shapes
//                     differ from the data's; a non-finite entry.
// `scales`: the s_ij of each frequency as the fit measures errors (idlib/fit's
// data_sigma); null: response_scales of the data.
ModelErrorModel model_error(const FrequencyResponse& data, const std::vector<Eigen::MatrixXcd>& model,
                            const std::vector<Eigen::MatrixXd>& sigma, const ModelErrorOptions& options,
                            const std::vector<Eigen::MatrixXd>* scales = nullptr);

// The failing bands of every channel, ordered by channel (output, then input) and
// frequency; data_index is copied into each.
std::vector<FailingBand> failing_bands(const ModelErrorModel& mem, const ModelErrorOptions& options,
                                       Index data_index = 0);

// A PHENOMENON: failing bands (of any channel and data set) that are one thing,
// because their largest error sits at nearly the same frequency (within
// phenomenon_decades, 0.1 decade).  Listed so that distinct phenomena are each
// shown, not five bands of one.  `where` says which channels in words: "the theta
// output row only", "the T_psi input column only", "the diagonal", or the list.
struct Phenomenon {
  std::vector<FailingBand> bands;  // members, furthest beyond the noise first
  double omega_rad_s = 0;          // where the representative's error is largest
  double max_sigma_ratio = 0;      // of the representative (bands.front())
  // Its bands' error_share summed over the data sets, over the number of data sets:
  // its share of the pooled squared error figure (exact when the sets' figures are
  // equal).  ranked_by_error_share orders by it.
  double error_share = 0;
  std::vector<Index> outputs, inputs;  // distinct channels involved (0-based)
  std::vector<Index> data_sets;        // distinct data sets involved
  std::string where;               // e.g. "the theta output row only (theta <- T_psi, theta <- F_z)"
};

// Groups the failing bands of every data set into phenomena, the furthest beyond
// the noise first (each located by its clearest band: diagnose seeds resonances from
// the first few, so a large mismatch in one place does not bury the narrow bands of a
// missing mode).  output_names / input_names label the channels (empty: 1-based
// numbers).
std::vector<Phenomenon> group_phenomena(const std::vector<std::vector<FailingBand>>& failures,
                                        const std::vector<std::string>& output_names,
                                        const std::vector<std::string>& input_names,
                                        double phenomenon_decades = 0.1);

// The same phenomena, the largest share of the error figure first (stable: ties keep
// their order).  What the user reads: a band far beyond a tiny noise at an entry near
// zero (issue 25: an off-diagonal at the lowest lines, "2-3e5 %, 400x the noise") holds
// little of the figure and is listed after the error that does.
std::vector<Phenomenon> ranked_by_error_share(std::vector<Phenomenon> phenomena);

// failures[d] are the bands of data set d.  A band whose channel has no
// overlapping band in some other data set gets differs_between_data = true and
// "; differs between data sets (only in set 1 of 3)" appended to its hint.
// Does nothing for fewer than two data sets.
void mark_differences_between_data(std::vector<std::vector<FailingBand>>& failures);

}  // namespace lpvid
