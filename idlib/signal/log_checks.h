// lpvid — habits of real logs that the identification methods do not model (issue 24:
// "saturated samples, a drift in a channel — detected and reported with the place, never
// silently used").  A jittered or missing sample and a non-finite value are refused
// when the log is read (formats/io/csv_log.h); an offset is estimated by every method
// (the Markov intercept, the simulation fits' offsets).  What is left, found here:
//
// Saturation: a channel held at its largest (or smallest) value in runs, the signature of
// a clipped sensor, amplifier or actuator.  Flagged when the value at the extreme
//   - occurs at least kMinSaturatedSamples times, in a run of at least 2 consecutive samples
//     (a periodic signal reaches its peak once per period: runs of 1),
//   - holds at least 3 times the samples of the three levels below it (the levels spaced
//     as the rail and the next level below it are): a quantised signal's top level is the
//     thin tail of its distribution, and a smooth extremum (a slow sine's turning point on
//     a fine encoder) spends as long at its top level as in the three below it, while a
//     clipped signal piles up at the rail and crosses the levels below fast,
//   - and that next level lies within 5 % of the channel's range of it (a binary signal
//     such as a PRBS jumps across the whole range: its levels are its design).
// A designed dwell (a setpoint held at its end position) passes these rules too.  When
// the log holds the setpoint (context below: any other column of the log), a channel
// whose rail runs are steps where some other, varying column holds its value too (at
// least kDwellShare of them) is taking a designed rest, not a clip: no finding (measured
// on a point-to-point log: the encoder sits at its largest count in the rests of 0.2 m,
// where the reference rests).  Otherwise the finding says "clipped, or a designed dwell".
//
// Drift: the least-squares line through the channel changes over the record by more than
// kDriftRatio times the rms of the channel about that line.  A stationary signal's fitted
// trend shrinks with the record (measured below, tests/idlib/signal/log_checks_test.cc); a
// random walk, a thermal drift or an integrator left open loop does not.  The methods fit
// an offset, not a trend, so the finding says so.
//
// Cost: two passes per channel, O(N) each.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

inline constexpr Index kMinSaturatedSamples = 3;
inline constexpr double kDwellShare = 0.9;
inline constexpr double kDriftRatio = 1.0;
inline constexpr Index kMinDriftSamples = 100;

struct ChannelFinding {
  enum class Kind { kSaturatedHigh, kSaturatedLow, kDrift };
  Kind kind = Kind::kDrift;
  Index channel = 0;
  Index first_row = 0, last_row = 0;  // saturated: the first and last sample at the rail; drift: 0, N - 1
  Index samples = 0;                  // saturated: samples at the rail
  Index longest_run = 0;              // saturated: the longest run of consecutive samples there
  double value = 0.0;                 // saturated: the rail; drift: the trend's change over the record
  double ratio = 0.0;                 // drift: |change| / rms about the trend
};

// | data: N × channels | findings sorted by channel, then kind.  Channels with fewer than
// 8 samples or no spread are skipped; the drift rule needs kMinDriftSamples (a record
// of a few dozen samples is mostly its start: a transient, not a drift).
// context: the log's columns (N × any, the checked ones among them or not), for the dwell
// rule; nullptr: none.
std::vector<ChannelFinding> inspect_channels(const Eigen::Ref<const Eigen::MatrixXd>& data,
                                             const Eigen::MatrixXd* context = nullptr);

// One sentence for a finding, naming the channel and the rows (1-based, as a user counts
// them in the file's data rows).
std::string describe_finding(const ChannelFinding& f, const std::string& channel_name);

}  // namespace lpvid
