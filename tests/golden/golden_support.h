// Golden-file tests: where the golden data lives and how results are scored.
//
// Scoring follows Ceres' examples/nist.cc: the log relative error
//   digits(a, b) = -log10(|a - b| / scale)
// is the number of leading decimal digits on which the fresh value a and the
// golden value b agree, measured against a scale that says what "relative" means
// for the quantity (a channel's peak, the largest singular value, ...; see each
// caller).  Identical values score kExactDigits.  A test requires the minimum
// score over all entries to reach a named threshold; it never diffs text.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <complex>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "formats/io/model_json.h"
#include "idlib/lti/frequency_response.h"
#include "tests/support/run_lpvid.h"

namespace lpvid::golden {

// A double holds 15.95 decimal digits; identical values (or differences below one
// unit in the last place of the scale) score this many.
constexpr double kExactDigits = 16.0;

inline std::string data_dir() { return std::string(LPVID_SOURCE_DIR) + "/tests/golden/data"; }
inline std::string data(const std::string& relative) { return data_dir() + "/" + relative; }

// The inputs every chain step reads (written by tests/golden/regenerate.sh; keep
// the arguments here and there identical).
inline std::string sim_dir() { return data("simulate/middle_1000hz"); }
inline std::string golden_logs() {
  return sim_dir() + "/exp_T_psi.csv " + sim_dir() + "/exp_T_theta.csv " + sim_dir() + "/exp_F_z.csv";
}
constexpr const char* kSimulateArgs = "--positions middle --rate-hz 1000 --duration-s 2 --seed 11";
constexpr const char* kChannels = "--excitation v1,v2,v3 --output q1,q2,q3";

// Digits of agreement of a with the golden b relative to scale (> 0), capped at
// kExactDigits; a zero scale means b is exactly zero: exact agreement or none.
inline double digits(double a, double b, double scale) {
  const double diff = std::abs(a - b);
  if (diff == 0.0) return kExactDigits;
  if (!(scale > 0.0) || !std::isfinite(diff)) return 0.0;
  return std::clamp(-std::log10(diff / scale), 0.0, kExactDigits);
}
inline double digits(std::complex<double> a, std::complex<double> b, double scale) {
  const double diff = std::abs(a - b);
  if (diff == 0.0) return kExactDigits;
  if (!(scale > 0.0) || !std::isfinite(diff)) return 0.0;
  return std::clamp(-std::log10(diff / scale), 0.0, kExactDigits);
}

// The worst score over a set of entries, and where it happened.
struct Score {
  double min_digits = kExactDigits;
  std::string where;
  void add(double d, const std::string& at) {
    if (d < min_digits) {
      min_digits = d;
      where = at;
    }
  }
};

// Frequency grid of the model comparisons: 1..3000 rad/s (the logs' Nyquist
// frequency is pi/Ts = 3142 rad/s), 200 points spaced evenly in log10.
constexpr double kGridLoRadS = 1.0;
constexpr double kGridHiRadS = 3000.0;
constexpr Index kGridPoints = 200;

// Compares two models by their frequency responses on the grid above: each
// entry G_ij(jw) scored relative to that channel's peak |G_ij| over the grid
// (golden model), so a channel's notch does not demand digits the peak never
// had.  Invariant under a change of state basis (STYLE.md item 11).
inline Score compare_frequency_response(const StateSpace& fresh, const StateSpace& golden) {
  const Eigen::VectorXd w = log_frequency_grid(kGridLoRadS, kGridHiRadS, kGridPoints);
  const auto a = evaluate_response(fresh, w);
  const auto b = evaluate_response(golden, w);
  Score score;
  for (Index i = 0; i < golden.num_outputs(); ++i) {
    for (Index j = 0; j < golden.num_inputs(); ++j) {
      double peak = 0;
      for (const auto& g : b) peak = std::max(peak, std::abs(g(i, j)));
      for (std::size_t k = 0; k < b.size(); ++k) {
        std::ostringstream at;
        at << "G(" << i << "," << j << ") at " << w[static_cast<Index>(k)] << " rad/s: fresh " << a[k](i, j)
           << ", golden " << b[k](i, j);
        score.add(digits(a[k](i, j), b[k](i, j), peak), at.str());
      }
    }
  }
  return score;
}

// Plain numeric CSV (comment lines starting with '#', one header line, numbers):
// returns the rows; the header goes to *header if given.
inline Eigen::MatrixXd read_numeric_csv(const std::string& path, std::vector<std::string>* header = nullptr) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open " + path);
  std::string line;
  bool seen_header = false;
  std::vector<std::vector<double>> rows;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> cells;
    std::stringstream s(line);
    for (std::string cell; std::getline(s, cell, ',');) cells.push_back(cell);
    if (!seen_header) {
      seen_header = true;
      if (header) *header = cells;
      continue;
    }
    std::vector<double> row;
    for (const auto& c : cells) row.push_back(std::stod(c));
    rows.push_back(std::move(row));
  }
  Eigen::MatrixXd m(static_cast<Index>(rows.size()), rows.empty() ? 0 : static_cast<Index>(rows.front().size()));
  for (std::size_t r = 0; r < rows.size(); ++r) {
    if (rows[r].size() != static_cast<std::size_t>(m.cols())) throw std::runtime_error("ragged row in " + path);
    for (std::size_t c = 0; c < rows[r].size(); ++c) m(static_cast<Index>(r), static_cast<Index>(c)) = rows[r][c];
  }
  return m;
}

// Reports a measured score in the test's XML output and on stdout.
inline void record_digits(const std::string& name, const Score& s) {
  ::testing::Test::RecordProperty(name, std::to_string(s.min_digits));
  std::cout << "[ digits   ] " << name << " = " << s.min_digits
            << (s.where.empty() ? " (identical)" : " (worst: " + s.where + ")") << "\n";
}

}  // namespace lpvid::golden
