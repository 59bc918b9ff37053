// lpvid — internals shared by the FRD readers and writers (frd_csv.cc,
// frd_mat.cc).  Not a public interface: include only from formats/io/frd_*.cc.
#pragma once

#include <numbers>
#include <string>
#include <string_view>

#include "idlib/core/types.h"

namespace lpvid::frd_detail {

// omega_rad_s = freq_hz * kTwoPi, one rounding (both readers use this product,
// so a CSV and a .mat file holding the same freq_hz give identical omegas).
inline constexpr double kTwoPi = 2.0 * std::numbers::pi;

// Limits of both readers (docs/formats.md, "Limits"): outputs and inputs per
// response, and entries (frequencies x outputs x inputs) of one response, so
// that a wrong or hostile file cannot ask for gigabytes.
inline constexpr Index kMaxChannels = 256;
inline constexpr Index kMaxEntries = Index{1} << 26;
// Largest sample rate a file may record (sample_rate_hz), Hz: far above any log
// lpvid reads, low enough that 1 / rate is a normal double.
inline constexpr double kMaxSampleRateHz = 1e12;

// A quantity prefix: letters and digits, not "coh".
bool quantity_allowed(std::string_view quantity);

double omega_from_hz(double hz);
// The freq_hz whose omega_from_hz is exactly omega when such a double exists
// (searched within a few ulps of omega / 2pi), else omega / 2pi.
double hz_from_omega(double omega);

// Throws InputError "cannot write 'path': ..." unless frd is writable: at least
// one frequency, finite positive strictly increasing omegas, consistent shapes,
// finite responses, coherence in [0, 1], name counts and names that are allowed.
void check_frd_for_writing(const std::string& path, const FrequencyResponse& frd);

}  // namespace lpvid::frd_detail
