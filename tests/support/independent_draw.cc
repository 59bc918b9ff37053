#include "tests/support/independent_draw.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>

namespace indep {
namespace {

struct Rng {
  explicit Rng(std::uint64_t seed) : g(seed) {}
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(g); }
  double log_uniform(double lo, double hi) { return std::exp(uniform(std::log(lo), std::log(hi))); }
  double sign() { return uniform(0, 1) < 0.5 ? -1.0 : 1.0; }
  std::mt19937_64 g;
};

std::string fmt_line(const char* name, double v) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "%s = %.6g\n", name, v);
  return buf;
}

}  // namespace

const char* hidden_name(HiddenEffect e) {
  switch (e) {
    case HiddenEffect::kNone: return "none";
    case HiddenEffect::kMode: return "mode";
    case HiddenEffect::kDelay: return "delay";
    case HiddenEffect::kCoilLag: return "coil_lag";
    case HiddenEffect::kComOffset: return "com_offset";
    case HiddenEffect::kRodTwist: return "rod_twist";
    case HiddenEffect::kSensorResonance: return "sensor_resonance";
    case HiddenEffect::kGain: return "gain";
  }
  return "?";
}

Draw draw_plant(std::uint64_t seed, const DrawOptions& o) {
  Rng r(seed * 7919 + 17);
  Draw d;
  Plant& p = d.plant;
  p = Plant::nominal();
  auto spread = [&](double v) { return v * r.uniform(1 - o.mass_spread, 1 + o.mass_spread); };
  p.m_p_kg = spread(p.m_p_kg);
  p.J_psi_kgm2 = spread(p.J_psi_kgm2);
  p.J_theta_kgm2 = spread(p.J_theta_kgm2);
  p.m_b_kg = spread(p.m_b_kg);
  p.z_b_m = r.uniform(0.03, 0.10);
  p.pitch_m = p.design_pitch_m = r.uniform(0.08, 0.13);
  const double dc = r.uniform(12, 40);
  for (int i = 0; i < 9; ++i) p.coil_damping_Ns_per_m(i) = dc * r.uniform(0.9, 1.1);
  p.rods = Plant::symmetric_rods(r.uniform(300, 900), r.uniform(20, 60), 0.0);
  p.extra_k_psi_Nm_per_rad = p.extra_k_theta_Nm_per_rad = 0;
  const double ratio = r.log_uniform(o.min_ratio, o.max_ratio);
  const Eigen::Matrix3d K = stiffness_matrix(p);
  if (K(0, 0) < ratio * K(1, 1))
    p.extra_k_psi_Nm_per_rad = ratio * K(1, 1) - K(0, 0);
  else
    p.extra_k_theta_Nm_per_rad = K(0, 0) / ratio - K(1, 1);
  for (int i = 0; i < 3; ++i) {
    d.pid.damping[i] = r.log_uniform(o.min_cl_damping, o.max_cl_damping);
    d.pid.integral_time_s[i] = r.log_uniform(o.min_integral_s, o.max_integral_s);
    d.pid.bandwidth_rad_s[i] = i < 2 ? r.uniform(25, 70) : r.uniform(12, 40);
  }
  d.noise_scale = r.log_uniform(o.min_noise_scale, o.max_noise_scale);
  if (o.allow_zero_noise && r.uniform(0, 1) < 0.25) d.noise_scale = 0;
  d.description = fmt_line("m_p_kg", p.m_p_kg) + fmt_line("J_psi_kgm2", p.J_psi_kgm2) +
                  fmt_line("J_theta_kgm2", p.J_theta_kgm2) + fmt_line("m_b_kg", p.m_b_kg) +
                  fmt_line("z_b_m", p.z_b_m) + fmt_line("pitch_m", p.pitch_m) + fmt_line("coil_damping", dc) +
                  fmt_line("k_vert_per_rod", p.rods[0].k_vert_N_per_m) +
                  fmt_line("k_bend_per_rod", p.rods[0].k_bend_Nm_per_rad) + fmt_line("psi_theta_ratio", ratio) +
                  fmt_line("cl_damping_psi", d.pid.damping[0]) + fmt_line("cl_damping_theta", d.pid.damping[1]) +
                  fmt_line("cl_damping_z", d.pid.damping[2]) + fmt_line("integral_s_psi", d.pid.integral_time_s[0]) +
                  fmt_line("integral_s_theta", d.pid.integral_time_s[1]) +
                  fmt_line("integral_s_z", d.pid.integral_time_s[2]) + fmt_line("noise_scale", d.noise_scale);
  return d;
}

void add_hidden_effect(Draw& d, HiddenEffect e, std::uint64_t seed, double Ts) {
  Rng r(seed * 104729 + 3);
  Plant& p = d.plant;
  switch (e) {
    case HiddenEffect::kNone: break;
    case HiddenEffect::kMode: {
      Mode m;
      m.omega_rad_s = r.uniform(400, 900);
      m.zeta = r.log_uniform(0.005, 0.05);
      m.shape = Eigen::VectorXd(9);
      const double size = r.uniform(1.0, 4.0);
      for (int i = 0; i < 9; ++i) m.shape(i) = r.uniform(-1, 1);
      m.shape *= size / m.shape.cwiseAbs().maxCoeff();
      p.modes.push_back(m);
      d.description += fmt_line("mode_omega", m.omega_rad_s) + fmt_line("mode_zeta", m.zeta);
      break;
    }
    case HiddenEffect::kDelay:
      p.input_delay_s = r.uniform(0.5, 3.0) * Ts;
      d.description += fmt_line("input_delay_s", p.input_delay_s);
      break;
    case HiddenEffect::kCoilLag: {
      const double corner_hz = r.uniform(50, 200);
      p.coil_lag_s = 1.0 / (2 * M_PI * corner_hz);
      d.description += fmt_line("coil_lag_s", p.coil_lag_s);
      break;
    }
    case HiddenEffect::kComOffset: {
      p.c_x_m = r.sign() * r.uniform(0.003, 0.012);
      p.c_y_m = r.sign() * r.uniform(0.003, 0.012);
      p.J_pt_kgm2 = r.sign() * r.uniform(0.005, 0.02) * p.J_psi_kgm2;
      const double ex = r.sign() * r.uniform(0.003, 0.012), ey = r.sign() * r.uniform(0.003, 0.012);
      for (Rod& rod : p.rods) {
        rod.x_m += ex;
        rod.y_m += ey;
      }
      d.description += fmt_line("com_x_m", p.c_x_m) + fmt_line("com_y_m", p.c_y_m) +
                       fmt_line("J_pt_kgm2", p.J_pt_kgm2) + fmt_line("stiffness_centre_x_m", ex) +
                       fmt_line("stiffness_centre_y_m", ey);
      break;
    }
    case HiddenEffect::kRodTwist: {
      // the rods twist: each tilt gains f times its clean stiffness (gravity aside),
      // f in [2, 5] drawn per axis — "tilt stiffness 2–5× the rods' bending,
      // differently on psi and theta" (rods 120° apart add the same twist to both
      // axes; the difference is an extra per-axis share)
      Plant clean = p;
      clean.beam_gravity = false;
      const Eigen::Matrix3d K0 = stiffness_matrix(clean);
      const double fpsi = r.uniform(2, 5), fth = r.uniform(2, 5);
      const double add_psi = fpsi * K0(0, 0), add_th = fth * K0(1, 1);
      const double common = std::min(add_psi, add_th);
      for (Rod& rod : p.rods) rod.k_twist_Nm_per_rad = common / 1.5;  // three rods 120° apart: 1.5 k per axis
      p.extra_k_psi_Nm_per_rad += add_psi - common;
      p.extra_k_theta_Nm_per_rad += add_th - common;
      const Eigen::Matrix3d K1 = stiffness_matrix(p);
      d.description += fmt_line("twist_factor_psi", fpsi) + fmt_line("twist_factor_theta", fth) +
                       fmt_line("K_psipsi_clean", K0(0, 0)) + fmt_line("K_psipsi_with_twist", K1(0, 0)) +
                       fmt_line("K_thth_clean", K0(1, 1)) + fmt_line("K_thth_with_twist", K1(1, 1));
      break;
    }
    case HiddenEffect::kGain: {
      // the amplifiers' or coils' force constant off the datasheet, the same on every
      // coil (one batch): 0.75-0.88 or 1.14-1.33 x.  On S alone this is exactly a
      // uniform scaling of M, D and K: only a known mass or force constant separates them.
      p.input_gain = r.sign() > 0 ? r.uniform(1.14, 1.33) : r.uniform(0.75, 0.88);
      d.description += fmt_line("input_gain", p.input_gain);
      break;
    }
    case HiddenEffect::kSensorResonance: {
      // theta output: H(s) = (s^2 + 2 zn wn s + wn^2)/(s^2 + 2 zp wp s + wp^2) * (wp/wn)^2,
      // a resonance at wp with a zero pair slightly above (unit DC gain)
      const double wp = r.uniform(400, 900), zp = r.uniform(0.02, 0.08);
      const double peak_db = r.uniform(6, 12);
      // peak ≈ (zn / zp) for wn ≈ wp: choose the zero damping for the peak
      const double zn = std::min(0.7, zp * std::pow(10.0, peak_db / 20.0));
      const double wn = wp * 1.15;
      ChannelFilter f;
      f.kind = ChannelFilter::kOutput;
      f.channel = 1;
      const double g = (wp * wp) / (wn * wn);
      f.b2 = g;
      f.b1 = g * 2 * zn * wn;
      f.b0 = g * wn * wn;
      f.a1 = 2 * zp * wp;
      f.a0 = wp * wp;
      p.filters.push_back(f);
      d.description += fmt_line("sensor_resonance_rad_s", wp) + fmt_line("sensor_resonance_zeta", zp);
      break;
    }
  }
}

Draw draw_stable(std::uint64_t seed, HiddenEffect effect, const DrawOptions& options, double Ts,
                 const std::vector<double>& beam_positions_m, int* redraws) {
  return draw_stable(seed, std::vector<HiddenEffect>{effect}, options, Ts, beam_positions_m, redraws);
}

Draw draw_stable(std::uint64_t seed, const std::vector<HiddenEffect>& effects, const DrawOptions& options, double Ts,
                 const std::vector<double>& beam_positions_m, int* redraws) {
  const Draw clean = draw_plant(seed, options);
  for (int attempt = 0; attempt < 20; ++attempt) {
    Draw d = clean;
    for (std::size_t k = 0; k < effects.size(); ++k)
      add_hidden_effect(d, effects[k], seed + 7919ULL * k + 1000003ULL * static_cast<std::uint64_t>(attempt), Ts);
    const Discrete C = pid_controller(d.plant, d.pid, Ts);
    bool stable = true;
    for (double xb : beam_positions_m) stable = stable && closed_loop_spectral_radius(sampled_plant(d.plant, xb, Ts), C) < 1.0;
    if (stable) {
      if (redraws) *redraws = attempt;
      return d;
    }
  }
  throw std::runtime_error("indep::draw_stable: the loop is unstable in 20 draws of the hidden effect");
}

bool levitate(Draw& draw, double Ts, const std::vector<double>& beam_positions_m) {
  for (Rod& r : draw.plant.rods) r.k_vert_N_per_m = r.k_bend_Nm_per_rad = r.k_twist_Nm_per_rad = 0;
  draw.plant.extra_k_psi_Nm_per_rad = draw.plant.extra_k_theta_Nm_per_rad = 0;
  draw.description += "levitated = true  # rods' stiffness and the extra tilt stiffness set to 0\n";
  const Discrete C = pid_controller(draw.plant, draw.pid, Ts);
  for (const double x : beam_positions_m)
    if (closed_loop_spectral_radius(sampled_plant(draw.plant, x, Ts), C) >= 1) return false;
  return true;
}

}  // namespace indep
