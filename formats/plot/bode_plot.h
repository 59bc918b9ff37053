// lpvid — Bode plots of MIMO frequency responses (models and FRD data overlaid).
//
// The figure is a grid of panels, one per (output, input) pair: row i is
// output i, column j is input j (FrequencyResponse layout, idlib/core/types.h).
// Each panel holds a magnitude axes (dB) and, when options.show_phase, a phase
// axes (deg) below it; panel titles read "from <input> to <output>".
//
//   +-------------------- title --------------------+
//   |  from u1 to y1        from u2 to y1           |
//   |  [magnitude dB]       [magnitude dB]          |   row = output
//   |  [phase deg]          [phase deg]             |
//   |  from u1 to y2        ...                     |
//   |        Frequency [rad/s]                      |
//   |        [legend: one entry per series]         |
//   +-----------------------------------------------+
//
// Axes: the frequency axis is log10, shared by all panels, spanning whole
// decades around the data (or [min_omega_rad_s, max_omega_rad_s] when given),
// with major grid lines at decades and minor ones at 2..9.  Each panel has its
// own magnitude range (ticks 1-2-5 x 10^k dB, 20 dB on typical ranges) and
// phase range (ticks at multiples of 45, 90, 180 ... deg).
//
// Data handling: magnitude 0 (-inf dB) points are skipped (the line joins its
// neighbours); NaN/inf entries break the line.  Phase is unwrapped per series
// along frequency and shifted by a multiple of 360 deg so that its first
// finite value lies in (-270, 90] deg (so model and data overlays agree).
// Frequencies in response.flagged are marked with a red cross on top.
#pragma once

#include <opencv2/core.hpp>

#include <string>
#include <vector>

#include "formats/plot/canvas.h"
#include "idlib/core/types.h"

namespace lpvid {

struct BodeSeries {
  std::string label;           // legend entry, e.g. "P left (identified)"
  FrequencyResponse response;  // outputs x inputs x frequency
  enum class Style { kLine, kDashed, kMarkers } style = Style::kLine;
  // Flagged frequencies (response.flagged) are drawn with a red cross on top.
  // false: magnitude only (e.g. the envelope of a band, whose phase is the estimate's);
  // such series are drawn first, under the others.
  bool show_phase = true;
};

struct BodePlotOptions {
  bool frequency_in_hz = false;  // x axis in Hz instead of rad/s
  bool show_phase = true;        // each panel = magnitude (dB) above phase (deg)
  std::string title;             // figure title; empty = none
  // Size of the plotting area of one panel's magnitude and phase axes; tick
  // labels, titles and legend are added around them.  Each must be >= 60.
  int panel_width_px = 420, magnitude_height_px = 260, phase_height_px = 150;
  // Frequency axis limits in rad/s (also when frequency_in_hz); 0 = from the
  // data, rounded outward to decades.  When both are given, min < max.
  double min_omega_rad_s = 0, max_omega_rad_s = 0;
  // Names used in panel titles; empty = the first series' response names,
  // falling back to "u1".. and "y1"...  When given, one per input / output.
  std::vector<std::string> input_labels, output_labels;
};

// Where things are in a rendered Bode figure (pixel coordinates), and the
// axis mappings used to draw them; exposed so tests can check positions.
struct BodeAxes {
  cv::Rect magnitude_px;      // plotting area of the magnitude axes
  cv::Rect phase_px;          // plotting area of the phase axes (empty if !show_phase)
  plot::AxisMap frequency;    // x, in the displayed unit (rad/s or Hz), log
  plot::AxisMap magnitude_db; // y of magnitude_px
  plot::AxisMap phase_deg;    // y of phase_px
  double magnitude_step_db = 0.0;  // tick spacing
  double phase_step_deg = 0.0;
};
struct BodeLayout {
  cv::Size figure;             // whole image
  Index outputs = 0, inputs = 0;
  std::vector<BodeAxes> panels;  // row-major: panels[out * inputs + in]
  cv::Rect legend_px;

  const BodeAxes& panel(Index output, Index input) const {
    return panels[static_cast<std::size_t>(output * inputs + input)];
  }
};

// Validates the input and computes the figure layout and axis ranges.
// @throws InputError (one line, naming the series and the problem) when
//   - series is empty, or a series has no frequencies;
//   - a series' response count differs from its frequency count, its
//     matrices differ in shape from each other or from the first series',
//     or a matrix is empty (0 outputs or 0 inputs);
//   - a frequency is not finite or not > 0 (the axis is logarithmic);
//   - flagged is neither empty nor one entry per frequency;
//   - options: panel sizes < 60 px, negative or non-finite frequency
//     limits, min >= max when both given, label counts that do not match.
BodeLayout layout_bode(const std::vector<BodeSeries>& series, const BodePlotOptions& options);

// Renders the figure (CV_8UC3, BGR, white background).  Throws as layout_bode.
cv::Mat render_bode(const std::vector<BodeSeries>& series, const BodePlotOptions& options);

// render_bode encoded as PNG bytes; the caller writes them to a file.
std::vector<unsigned char> bode_png(const std::vector<BodeSeries>& series,
                                    const BodePlotOptions& options);

// Phase of the values in degrees, unwrapped along the sequence (jumps larger
// than 180 deg between consecutive finite values removed) and shifted by a
// multiple of 360 deg so that the first finite value lies in (-270, 90].
// Non-finite values (and zeros, whose phase is undefined) give NaN and do not
// reset the unwrapping.
std::vector<double> unwrapped_phase_deg(const std::vector<Complex>& values);

}  // namespace lpvid
