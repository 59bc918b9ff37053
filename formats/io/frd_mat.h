// lpvid — frequency-response (FRD) data in MATLAB .mat files (docs/formats.md,
// "FRD files").  Data layout: idlib/core/types.h.  v5 (MATLAB's default '-v7'
// save, compressed or not) is read by lpvid itself, every size checked against
// the bytes present (a truncated or damaged file is an error, never a value read
// from nowhere); v7.3 (HDF5) is read through libmatio; both are written with
// libmatio.  Limits: a regular file (not a pipe) of at most 512 MiB, variables
// of at most 512 MiB uncompressed, responses of at most 256 outputs and inputs
// and 2^26 entries.
//
// Variables (MATLAB names):
//   frequency (one of)  freq_hz, f, freq   in Hz:    omega_rad_s = 2*pi*f
//                       w, omega           in rad/s: used as is
//                       a real vector of nf > 0 entries, positive, strictly increasing.
//   response            FrdReadOptions::quantity if given, else the one of
//                       S, P, G, H, frd present: an ny x nu x nf array,
//                       complex or real (real = zero imaginary part); also an
//                       ny x nu matrix when nf = 1, or a vector of nf entries
//                       for one output and one input.  Finite.
//   coh (optional)      coherence, real, the same shape as the response, in [0, 1].
//   var, dvar (optional) variance (total) and its nonlinear-distortion part, real,
//                       the response's shape, >= 0, dvar <= var (dvar needs var).
//   flag (optional)     nf entries, 0 or 1 (double or logical): 1 = untrusted.
//   sample_rate_hz (optional) one number > 0: the rate of the log the response
//                       was estimated from (FrequencyResponse::sample_rate_hz).
//   averages (optional) one number >= 1 (FrequencyResponse::averages).
//   outputs, inputs     (optional) cell arrays of ny / nu char names.
// Numeric classes double, single and the integer classes are read (converted
// to double).  Other variables are ignored.
#pragma once

#include <string>

#include "formats/io/frd_csv.h"
#include "idlib/core/types.h"

namespace lpvid {

// Reads an FRD .mat file.  Throws InputError "path: what; what to do", e.g.
//   "cannot open 'x.mat': No such file or directory; check the path"
//   "'x.mat' is not a MATLAB .mat file (v5 or v7.3); check the file, or save it in MATLAB with save(name, '-v7')"
//   "'x.mat' has no frequency variable; give one of freq_hz, f, freq (Hz) or w, omega (rad/s); the file holds: S"
//   "'x.mat': response 'S' is 2×3×5 but there are 4 frequencies; give an outputs × inputs × frequencies array"
FrequencyResponse read_frd_mat(const std::string& path, const FrdReadOptions& options = {});

enum class MatVersion { kV5, kV73 };

// Writes freq_hz (nf x 1, chosen as write_frd_csv does so that omegas read back
// identically), <quantity> (ny x nu x nf, complex), coh when frd.coherence is
// not empty, averages / sample_rate_hz when > 0, flag (nf x 1 double) when frd.flagged is not empty, and
// outputs/inputs (cell arrays of char) for named axes; uncompressed.  Atomic:
// a temporary ".<name>.tmp.<pid>.<n>" in the target's directory is renamed over
// the target when complete.  Throws InputError on the rules of write_frd_csv,
// for "-" (a .mat file cannot go to stdout) and when the file cannot be written.
void write_frd_mat(const std::string& path, const FrequencyResponse& frd, const std::string& quantity,
                   MatVersion version = MatVersion::kV5);
// The same into a staged file (AtomicOutputSet::stage); the caller commits.  A
// file that streams ("-", a FIFO, a device) is refused: matio writes by name.
void write_frd_mat(AtomicFileWriter& out, const FrequencyResponse& frd, const std::string& quantity,
                   MatVersion version = MatVersion::kV5);

}  // namespace lpvid
