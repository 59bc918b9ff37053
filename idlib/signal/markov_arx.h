// lpvid — Markov parameters through a high-order ARX model (the observer / OKID idea):
// for a response too slow for the record (a lightly damped mode whose impulse response
// has not died out within any horizon the record supports), the finite impulse response
// of estimate_markov's least squares is truncated, and its last lags soak up the tail
// (measured on the DaISy robot arm: 256 lags from 1024 samples, the last lag 0.235
// where the response there is about -0.03).  An ARX model, per output i,
//
//   q_i(t) = Σ_{k=1}^{n} a_k q_i(t − k) + Σ_{k=0}^{n} B_k v(t − k) + c_e + e(t)
//
// describes the same response with a short memory (its one-step predictor is an observer
// whose poles the least squares places: OKID, Juang, Phan, Horta & Longman 1993; high-
// order ARX, Ljung & Wahlberg 1992 — consistent as n grows with the data, in open and in
// closed loop, for any excitation spectrum).  Every output of a linear system shares the
// characteristic polynomial, so a scalar autoregressive part per output holds the system
// (n at least its number of states, more for the noise's colour).  Not the full vector
// ARX, whose autoregressive part couples the outputs: on the DaISy steel subframe (28
// accelerometers, 2 forces) it carried a pole near |z| = 3 at every order from 2 to 35
// (a relation between outputs, not the structure's dynamics) and its response grew
// without bound.  The Markov parameters of v -> q_i follow by the recursion
//
//   g[0] = B_0,   g[k] = B_k + Σ_{j=1}^{min(k, n)} a_j g[k − j]   (B_k = 0 for k > n),
//
// to any number of lags.
//
// The order n, per output: Akaike's criterion with its small-sample correction (Hurvich
// & Tsai), AICc(n) = N' log σ̂²_n + N' (N' + k_n) / (N' − k_n − 2), k_n = m + n (1 + m),
// every order n = 1 .. n_max fitted on the same samples t = n_max .. N − 1 of each
// experiment (so that the criteria compare like with like); the best-scored order whose
// autoregressive part lets the response decay (or hold, as an integrator: |z| up to
// 1 + 0.1 / L); noise-free data take the first order whose residual is round-off.
// n_max = min(L, 60, the largest n with N' >= 8 k_n).
//
// Normal equations from the records' correlations (blocked FFT, O(N (1 + m)² log n_max)
// per output) with exact corrections at the record ends and an intercept per experiment
// (each experiment's window centred); one dense solve per order.
#pragma once

#include <vector>

#include "idlib/signal/markov.h"

namespace lpvid {

// Called by estimate_markov for MarkovOptions::Method::kArx (after its checks of the
// experiments); fills g[0..L], arx_order, arx_max_order, arx_criterion,
// arx_spectral_radius and report (estimate_markov then sets noise_std as least squares
// defines it, from the residual of g as a finite impulse response, and the RMS values).
// @throws InputError  a record too short for order 1 (N' < 8 k_1 / p), or an
//   options.arx_order beyond what the records support (the message says the limit).
MarkovResult estimate_markov_arx(const std::vector<ExperimentView>& experiments, const MarkovOptions& options);

}  // namespace lpvid
