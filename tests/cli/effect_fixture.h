// A user-defined effect file shared by the CLI tests (model define, bad input): a
// resonance of the theta sensor's mount, in the format of docs/formats.md,
// "Effect definition files".
#pragma once

namespace lpvid::testing {

inline constexpr const char* kMountEffect = R"({"name": "theta_mount", "description": "theta sensor mount",
 "blocks": [{"kind": "resonance", "side": "output", "channels": ["theta"],
             "parameters": ["wp_rad_s", "zp", "wz_rad_s", "zz"]}],
 "parameters": {"wp_rad_s": {"value": 800, "unit": "rad/s", "lower": 300, "upper": 3000, "free": true},
                "zp": {"value": 0.05, "unit": "1", "lower": 0.001, "upper": 0.7, "free": true},
                "wz_rad_s": {"value": 900, "unit": "rad/s", "lower": 300, "upper": 3000, "free": true},
                "zz": {"value": 0.1, "unit": "1", "lower": 0.001, "upper": 0.7, "free": true}}})";

}  // namespace lpvid::testing
