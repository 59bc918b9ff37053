#include "idlib/lti/transfer_function.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "idlib/core/error.h"
#include "idlib/lti/interconnect.h"

namespace lpvid {
namespace {

void check_finite(const std::vector<double>& v, const char* what) {
  for (size_t k = 0; k < v.size(); ++k)
    if (!std::isfinite(v[k]))
      throw InputError(fmt::format("{} coefficient {} is {}; give finite numbers", what, k + 1, v[k]));
}

// num/den as b, a in ascending powers of z^-1, a[0] = 1, equal lengths n + 1.
struct Normalized {
  std::vector<double> b, a;
};

Normalized normalize(std::vector<double> num, std::vector<double> den, TfVariable variable) {
  if (den.empty()) throw InputError("the denominator is empty; give its coefficients, e.g. \"den\": [1, -0.5]");
  if (num.empty()) throw InputError("the numerator is empty; give its coefficients ([0] for a zero element)");
  check_finite(num, "numerator");
  check_finite(den, "denominator");
  Normalized out;
  if (variable == TfVariable::kZ) {
    if (den[0] == 0)
      throw InputError(fmt::format("the denominator's leading coefficient (of z^{}) is 0; remove the leading zeros "
                                   "(\"variable\": \"z\" lists descending powers of z)",
                                   den.size() - 1));
    while (num.size() > 1 && num[0] == 0) num.erase(num.begin());
    if (num.size() > den.size())
      throw InputError(fmt::format("the numerator has degree {} in z but the denominator only {}: the element is "
                                   "improper (not causal); check the coefficients, or use \"variable\": \"z^-1\" if "
                                   "they are in powers of z^-1",
                                   num.size() - 1, den.size() - 1));
    out.b.assign(den.size() - num.size(), 0.0);
    out.b.insert(out.b.end(), num.begin(), num.end());
    out.a = std::move(den);
  } else {
    if (den[0] == 0)
      throw InputError("the denominator's first coefficient (of z^0) is 0: the element is not causal; check the "
                       "coefficients, or use \"variable\": \"z\" if they are in descending powers of z");
    while (num.size() > 1 && num.back() == 0) num.pop_back();
    while (den.size() > 1 && den.back() == 0) den.pop_back();
    const size_t len = std::max(num.size(), den.size());
    num.resize(len, 0.0);
    den.resize(len, 0.0);
    out.b = std::move(num);
    out.a = std::move(den);
  }
  const double a0 = out.a[0];
  for (double& v : out.b) v /= a0;
  for (double& v : out.a) v /= a0;
  out.a[0] = 1.0;
  return out;
}

// Diagonal similarity by powers of two (exact) balancing the off-diagonal row and
// column sums of A (Parlett & Reinsch 1969, as LAPACK dgebal's scaling step).
void balance(StateSpace& s) {
  const Index n = s.A.rows();
  constexpr int kMaxSweeps = 64;  // each sweep moves a scale by a factor 2 at least; 64 bound the exponents
  for (int sweep = 0; sweep < kMaxSweeps; ++sweep) {
    bool changed = false;
    for (Index i = 0; i < n; ++i) {
      double c = 0, r = 0;
      for (Index j = 0; j < n; ++j)
        if (j != i) {
          c += std::abs(s.A(j, i));
          r += std::abs(s.A(i, j));
        }
      if (c == 0 || r == 0) continue;
      const double total = c + r;
      double f = 1;
      double g = r / 2;
      while (c < g) {
        f *= 2;
        c *= 4;
      }
      g = r * 2;
      while (c >= g) {
        f /= 2;
        c /= 4;
      }
      if ((c + r) / f < 0.95 * total) {
        changed = true;
        s.A.row(i) /= f;
        s.A.col(i) *= f;
        s.B.row(i) /= f;
        s.C.col(i) *= f;
      }
    }
    if (!changed) break;
  }
}

StateSpace observer_form(const Normalized& p, double sample_period_s) {
  const Index n = static_cast<Index>(p.a.size()) - 1;
  StateSpace s;
  s.sample_period_s = sample_period_s;
  s.A = Eigen::MatrixXd::Zero(n, n);
  s.B.resize(n, 1);
  s.C = Eigen::MatrixXd::Zero(1, n);
  s.D = Eigen::MatrixXd::Constant(1, 1, p.b[0]);
  for (Index i = 0; i < n; ++i) {
    const size_t k = static_cast<size_t>(i) + 1;
    s.A(i, 0) = -p.a[k];
    if (i + 1 < n) s.A(i, i + 1) = 1.0;
    s.B(i, 0) = p.b[k] - p.a[k] * p.b[0];
  }
  if (n > 0) s.C(0, 0) = 1.0;
  balance(s);
  return s;
}

StateSpace static_gain(double k, double sample_period_s) {
  StateSpace s;
  s.sample_period_s = sample_period_s;
  s.A.resize(0, 0);
  s.B.resize(0, 1);
  s.C.resize(1, 0);
  s.D = Eigen::MatrixXd::Constant(1, 1, k);
  return s;
}

// A group of roots: a conjugate pair (one value with imag > 0), two reals, or one real.
struct Group {
  std::vector<Complex> roots;
  int degree() const { return static_cast<int>(roots.size()); }
  double reach() const {  // largest |root|
    double r = 0;
    for (const Complex& z : roots) r = std::max(r, std::abs(z));
    return r;
  }
  // Coefficients in descending powers of z of Π(z − r) (real).
  std::vector<double> poly() const {
    if (roots.empty()) return {1.0};
    if (roots.size() == 1) return {1.0, -roots[0].real()};
    if (roots[0].imag() != 0) return {1.0, -2 * roots[0].real(), std::norm(roots[0])};
    return {1.0, -(roots[0].real() + roots[1].real()), roots[0].real() * roots[1].real()};
  }
};

std::vector<Group> group_roots(const std::vector<Complex>& values, const char* what) {
  std::vector<Complex> reals;
  std::vector<Group> groups;
  std::vector<bool> used(values.size(), false);
  for (size_t i = 0; i < values.size(); ++i) {
    const Complex v = values[i];
    if (!std::isfinite(v.real()) || !std::isfinite(v.imag()))
      throw InputError(fmt::format("{} {} is not finite; give finite numbers", what, i + 1));
    if (v.imag() == 0) {
      reals.push_back(v);
      used[i] = true;
    }
  }
  for (size_t i = 0; i < values.size(); ++i) {
    if (used[i] || values[i].imag() < 0) continue;
    const Complex v = values[i];
    size_t partner = values.size();
    for (size_t j = 0; j < values.size(); ++j)
      if (!used[j] && values[j].imag() < 0 &&
          std::abs(values[j] - std::conj(v)) <= kConjugateRelTolerance * std::max(std::abs(v), std::abs(values[j]))) {
        partner = j;
        break;
      }
    if (partner == values.size()) break;  // reported below
    used[i] = used[partner] = true;
    groups.push_back({{v, std::conj(v)}});
  }
  for (size_t i = 0; i < values.size(); ++i)
    if (!used[i])
      throw InputError(fmt::format("{} {} = [{}, {}] has no complex-conjugate partner; complex {}s must come in "
                                   "conjugate pairs (real coefficients): add [{}, {}]",
                                   what, i + 1, values[i].real(), values[i].imag(), what, values[i].real(),
                                   -values[i].imag()));
  std::sort(reals.begin(), reals.end(), [](Complex a, Complex b) { return std::abs(a) > std::abs(b); });
  for (size_t k = 0; k + 1 < reals.size(); k += 2) groups.push_back({{reals[k], reals[k + 1]}});
  if (reals.size() % 2 == 1) groups.push_back({{reals.back()}});
  return groups;
}

double distance(const Group& a, const Group& b) {
  double d = std::numeric_limits<double>::infinity();
  for (const Complex& x : a.roots)
    for (const Complex& y : b.roots) d = std::min(d, std::abs(x - y));
  return d;
}

StateSpace realize_zpk(const SisoTf& tf, TfVariable variable, double sample_period_s) {
  if (!std::isfinite(tf.gain)) throw InputError(fmt::format("the gain is {}; give a finite number", tf.gain));
  std::vector<Complex> zeros = tf.zeros, poles = tf.poles;
  std::vector<Group> zero_groups = group_roots(zeros, "zero");
  std::vector<Group> sections = group_roots(poles, "pole");
  if (variable == TfVariable::kZInverse) {
    // k Π(1 − z_i z^-1) / Π(1 − p_i z^-1) = k z^(np−nz) Π(z − z_i) / Π(z − p_i).
    if (poles.size() > zeros.size()) zeros.resize(poles.size(), Complex(0, 0));
    if (zeros.size() > poles.size()) poles.resize(zeros.size(), Complex(0, 0));
    zero_groups = group_roots(zeros, "zero");
    sections = group_roots(poles, "pole");
  } else if (zeros.size() > poles.size()) {
    throw InputError(fmt::format("{} zeros but {} poles: the element is improper (not causal) in z; check the zeros, "
                                 "or use \"variable\": \"z^-1\" for factors (1 − z_i z^-1)",
                                 zeros.size(), poles.size()));
  }
  if (tf.gain == 0 || sections.empty()) return static_gain(tf.gain, sample_period_s);
  std::stable_sort(sections.begin(), sections.end(), [](const Group& a, const Group& b) { return a.reach() > b.reach(); });
  // Zeros to sections: each pair to the nearest second-order section still free;
  // a single real zero to the first-order section if any, else to a free second-order one.
  std::vector<int> zero_of(sections.size(), -1);
  std::vector<bool> taken(zero_groups.size(), false);
  for (size_t s = 0; s < sections.size(); ++s) {
    if (sections[s].degree() != 2) continue;
    int best = -1;
    for (size_t z = 0; z < zero_groups.size(); ++z)
      if (!taken[z] && zero_groups[z].degree() == 2 &&
          (best < 0 || distance(zero_groups[z], sections[s]) < distance(zero_groups[static_cast<size_t>(best)], sections[s])))
        best = static_cast<int>(z);
    if (best >= 0) {
      zero_of[s] = best;
      taken[static_cast<size_t>(best)] = true;
    }
  }
  for (size_t z = 0; z < zero_groups.size(); ++z) {
    if (taken[z]) continue;
    LPVID_ASSERT(zero_groups[z].degree() == 1);  // pairs always fit (nz <= np)
    size_t target = sections.size();
    for (size_t s = 0; s < sections.size(); ++s)
      if (sections[s].degree() == 1) target = s;
    if (target == sections.size())
      for (size_t s = 0; s < sections.size() && target == sections.size(); ++s)
        if (zero_of[s] < 0) target = s;
    LPVID_ASSERT(target < sections.size());
    zero_of[target] = static_cast<int>(z);
    taken[z] = true;
  }
  StateSpace out;
  for (size_t s = 0; s < sections.size(); ++s) {
    std::vector<double> num = zero_of[s] < 0 ? std::vector<double>{1.0} : zero_groups[static_cast<size_t>(zero_of[s])].poly();
    if (s + 1 == sections.size())
      for (double& v : num) v *= tf.gain;
    const StateSpace section = observer_form(normalize(num, sections[s].poly(), TfVariable::kZ), sample_period_s);
    out = s == 0 ? section : series(out, section);
  }
  return out;
}

void check_period(double sample_period_s) {
  if (!(sample_period_s > 0) || !std::isfinite(sample_period_s))
    throw InputError(fmt::format("sample period {} s is not allowed; a transfer function here is discrete: give ts > 0",
                                 sample_period_s));
}

Complex horner(const std::vector<double>& c, Complex x) {
  Complex v(0, 0);
  for (const double a : c) v = v * x + a;
  return v;
}

}  // namespace

StateSpace realize_siso(const SisoTf& tf, TfVariable variable, double sample_period_s) {
  check_period(sample_period_s);
  if (tf.is_zpk) return realize_zpk(tf, variable, sample_period_s);
  return observer_form(normalize(tf.num, tf.den, variable), sample_period_s);
}

StateSpace realize_tf_matrix(const std::vector<std::optional<SisoTf>>& entries, Index outputs, Index inputs,
                             TfVariable variable, double sample_period_s) {
  LPVID_ASSERT(static_cast<Index>(entries.size()) == outputs * inputs);
  check_period(sample_period_s);
  std::vector<StateSpace> parts(entries.size());
  Index n = 0;
  for (size_t k = 0; k < entries.size(); ++k)
    if (entries[k]) {
      try {
        parts[k] = realize_siso(*entries[k], variable, sample_period_s);
      } catch (const InputError& e) {
        throw InputError(fmt::format("element ({}, {}): {}", static_cast<Index>(k) / inputs + 1,
                                     static_cast<Index>(k) % inputs + 1, e.what()));
      }
      n += parts[k].order();
    }
  StateSpace s;
  s.sample_period_s = sample_period_s;
  s.A = Eigen::MatrixXd::Zero(n, n);
  s.B = Eigen::MatrixXd::Zero(n, inputs);
  s.C = Eigen::MatrixXd::Zero(outputs, n);
  s.D = Eigen::MatrixXd::Zero(outputs, inputs);
  Index at = 0;
  for (size_t k = 0; k < entries.size(); ++k) {
    if (!entries[k]) continue;
    const Index i = static_cast<Index>(k) / inputs, j = static_cast<Index>(k) % inputs;
    const StateSpace& p = parts[k];
    const Index m = p.order();
    s.A.block(at, at, m, m) = p.A;
    s.B.block(at, j, m, 1) = p.B;
    s.C.block(i, at, 1, m) = p.C;
    s.D(i, j) = p.D(0, 0);
    at += m;
  }
  return s;
}

Complex evaluate_siso(const SisoTf& tf, TfVariable variable, double sample_period_s, double omega_rad_s) {
  const Complex z = std::polar(1.0, omega_rad_s * sample_period_s);
  if (!tf.is_zpk) {
    if (variable == TfVariable::kZ) return horner(tf.num, z) / horner(tf.den, z);
    // Ascending powers of z^-1: Horner in w = z^-1 over the reversed coefficients.
    const Complex w = 1.0 / z;
    const std::vector<double> b(tf.num.rbegin(), tf.num.rend()), a(tf.den.rbegin(), tf.den.rend());
    return horner(b, w) / horner(a, w);
  }
  Complex v = tf.gain;
  for (const Complex& q : tf.zeros) v *= variable == TfVariable::kZ ? z - q : 1.0 - q / z;
  for (const Complex& p : tf.poles) v /= variable == TfVariable::kZ ? z - p : 1.0 - p / z;
  return v;
}

}  // namespace lpvid
