#include "cli/responses.h"

#include <fmt/format.h>

#include <cmath>

#include "formats/io/frd_csv.h"
#include "formats/io/frd_mat.h"
#include "formats/io/model_json.h"
#include "formats/io/response_file.h"
#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"

namespace lpvid::cli {
namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

LoadedResponse load_response(const std::string& path) {
  ResponseFile file = read_response_file(path);
  return {path, std::move(file.model), std::move(file.frd)};
}

StateSpace read_controller(const std::string& path) {
  StateSpace c = read_state_space(path);
  const bool zero = c.D.isZero(0.0) && (c.B.isZero(0.0) || c.C.isZero(0.0));
  if (zero)
    throw InputError(fmt::format("{}: the controller is zero at every frequency (D = 0 and B or C = 0), as if the loop "
                                 "were open, so no plant can be recovered through it; give the controller that ran",
                                 path == "-" ? "<stdin>" : path));
  return c;
}

bool is_measured_controller(const std::string& path) { return path != "-" && !ends_with(path, ".json"); }

FrequencyResponse read_measured_controller(const std::string& path) {
  FrequencyResponse c = load_frd_merged({path});
  bool zero = true;
  for (const Eigen::MatrixXcd& m : c.response) zero = zero && m.isZero(0.0);
  if (zero)
    throw InputError(fmt::format("{}: the measured controller is zero at every frequency, as if the loop were open, "
                                 "so no plant can be recovered through it; give the controller that ran",
                                 path));
  return c;
}

FrequencyResponse load_frd_merged(const std::vector<std::string>& paths) {
  if (paths.empty()) throw InputError("no frequency-response file given; give one or more FRD files (.csv, .mat)");
  for (const auto& p : paths)
    if (ends_with(p, ".json"))
      throw InputError(fmt::format("'{}' is a model file; give frequency-response data (FRD .csv or .mat) here", p));
  if (paths.size() == 1) {
    LoadedResponse r = load_response(paths.front());
    if (!r.frd)  // stdin holding a model
      throw InputError(fmt::format("'{}' holds a model; give frequency-response data (FRD .csv or .mat) here",
                                   paths.front() == "-" ? "<stdin>" : paths.front()));
    return std::move(*r.frd);
  }
  std::vector<FrdPart> parts;
  for (const auto& p : paths) {
    if (ends_with(p, ".mat")) {
      // A .mat file holds the whole array: every pair.
      FrdPart part;
      part.path = p;
      part.frd = read_frd_mat(p);
      for (Index i = 0; i < part.frd.num_outputs(); ++i)
        for (Index j = 0; j < part.frd.num_inputs(); ++j) part.pairs.emplace_back(i, j);
      parts.push_back(std::move(part));
    } else {
      parts.push_back(read_frd_part(p));
    }
  }
  // read_frd_mat does not report which response variable it took; a .mat part
  // counts as holding the quantity of the CSV parts, so that mixing the two is
  // judged by the pairs each holds (not refused as "quantity '' vs 'S'").
  for (const FrdPart& q : parts)
    if (!q.quantity.empty()) {
      for (FrdPart& part : parts)
        if (part.quantity.empty()) part.quantity = q.quantity;
      break;
    }
  return merge_frd_parts(parts);
}

FrequencyResponse response_on(const LoadedResponse& r, const Eigen::VectorXd& omega) {
  if (r.model) return frequency_response(*r.model, omega);
  const FrequencyResponse& f = *r.frd;
  // Two grids are the same when every frequency agrees to 1e-9 relative
  // (CSV round trips are exact; analyzers write the same grid for every file).
  constexpr double kSameGrid = 1e-9;
  bool same = f.omega_rad_s.size() == omega.size();
  for (Index k = 0; same && k < omega.size(); ++k)
    same = std::abs(f.omega_rad_s(k) - omega(k)) <= kSameGrid * omega(k);
  if (!same)
    throw InputError(fmt::format("{}: its {} frequencies are not those of the other response; compare data on one grid "
                                 "(or compare a model with data)",
                                 r.path, f.omega_rad_s.size()));
  return f;
}

}  // namespace lpvid::cli
