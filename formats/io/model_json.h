// lpvid — state-space model files (JSON), docs/formats.md.
//
//   {
//     "type": "state_space",
//     "ts": 0.001,
//     "inputs": ["v1"],
//     "outputs": ["q1"],
//     "A": [[0.9, 0.1], [0, 0.8]],
//     "B": [[0], [1]],
//     "C": [[1, 0]],
//     "D": [[0]]
//   }
//
// Matrices are row-major nested arrays: a matrix with r rows is an array of r
// rows, each an array of its entries.  A matrix with no rows is written [] (its
// column count follows from the other matrices); a matrix with rows but no
// columns is written as empty rows ([[], []] for C of a 2-output static gain).
// Dimensions: n = rows of A; m = number of "inputs" if given, else columns of D
// (if D has rows), else columns of B; p = number of "outputs" if given, else rows
// of D.  "ts" is the sample period in s, 0 for continuous time.  "inputs" and
// "outputs" are optional; other keys (e.g. "provenance") are allowed and ignored.
// JSON has no NaN or Inf: every entry must be a number.
//
// A file may instead hold a discrete transfer-function matrix (a controller as a
// lab writes it), converted to state space on reading (idlib/lti/transfer_function.h;
// docs/formats.md, "Transfer-function controllers"):
//   {"type": "transfer_function", "ts": 1e-4, "variable": "z" | "z^-1",
//    "inputs": [...], "outputs": [...],
//    "diagonal": [element, ...]  or  "matrix": [[element, ...], ...]}
// element = {"num": [...], "den": [...]} | {"zeros": [...], "poles": [...], "gain": k}
// (a zero or pole: a number or [re, im]); a matrix entry 0 or null is a zero element.
// Errors point at the key and name the element: "ctl.json:5:3: key 'diagonal'
// element (2, 2): the denominator's leading coefficient (of z^2) is 0; ...".
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "formats/io/atomic_file.h"
#include "idlib/core/types.h"

namespace lpvid {

// Reads a model file; "-" reads stdin.  Throws InputError
//   "ctl.json:3:14: invalid JSON: <what nlohmann found>; fix the JSON syntax"
//   "ctl.json:7:3: key 'B' must be a 3×1 matrix (states × inputs), got 3×2; ..."
// and whatever StateSpace::validate() rejects (prefixed with the path).
// Limits (docs/formats.md, "Limits"): the file at most 64 MiB, nesting at most
// 64 levels, at most kMaxModelStates states and kMaxModelChannels inputs and
// outputs: "big.json:9:3: key 'A' has 1000 rows: lpvid reads models of at most
// 400 states; reduce the model first (e.g. realize --order)".
StateSpace read_state_space(const std::string& path);
// The same from text already read (path for messages only; content detection of stdin).
StateSpace parse_state_space(const std::string& text, const std::string& path);

// True when path is a regular file of JSON whose "type" is "state_space" or
// "transfer_function" (nothing else validated: read_state_space says what is wrong).
bool is_state_space_file(const std::string& path);

// Largest model a file may hold: unloop's interconnection of two such models
// takes about 1 s at 400 + 400 states (2 cores; cubic in the order).
inline constexpr Index kMaxModelStates = 400;
inline constexpr Index kMaxModelChannels = 256;

// The file text: pretty, one matrix row per line, numbers that read back to the
// identical doubles.  extra must be null or an object; its keys are written after
// the model's (a key of the schema in extra is an InputError).  Calls validate().
std::string state_space_to_json(const StateSpace& model, const nlohmann::json& extra = {});

// Writes state_space_to_json(model, extra) atomically (atomic_file.h); "-" is stdout.
void write_state_space(const std::string& path, const StateSpace& model, const nlohmann::json& extra = {});

}  // namespace lpvid
