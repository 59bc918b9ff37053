#!/usr/bin/env python3
"""What a linear model of N modes can reach on the F-16's periodic FRF, independent of lpvid.

Usage:  python3 scripts/f16-rational-bound.py ../shared/real-data/f16_gvt/f16_fullmsine_level1.csv
Needs numpy (apt-get install python3-numpy); not part of the test suite or the main job.

From the log (9 periods of 8192 samples, the first dropped): the periodic FRF force ->
acc1..3 at the excited bins 41..307 (period means; its variance from the period-to-period
scatter, errors in variables, as `lpvid frf --method periodic`), lpvid's error figure and
noise floor (docs/math.md, "Error figure and noise floor": the scale floored at 0.1 x the
largest |H| within +-0.1 decade and at 3 x the noise rms), and for N pole pairs:

  free:  vector fitting (Gustavsen & Semlyen 1999): common poles, complex residues per
         output, plus d + e s, each line weighed by 1/scale (the figure's own weighting),
         30 pole relocations from poles spread over the band;
  real:  the same poles, real residues of s^2/(s^2 + 2 zeta w s + w^2) per output (a
         proportionally damped mode seen by accelerometers, lpvid's structural_mode) plus
         the residual terms d + e s^2 (the modes below and above the band);
  real, no residual terms: as real, without d + e s^2.

Printed: N, the three figures, and the poles in Hz.  docs/real-data.md quotes the table.
"""
import sys

import numpy as np


def load(path):
    rows = []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or line.startswith("t"):
                continue
            rows.append([float(x) for x in line.split(",")])
    return np.array(rows)


def main(path):
    d = load(path)
    period, periods, fs = 8192, 9, 400.0
    u = d[:, 2].reshape(periods, period)[1:]
    y = d[:, 3:6].T.reshape(3, periods, period)[:, 1:]
    lines = slice(41, 308)
    U = np.fft.fft(u, axis=1)[:, lines]
    Y = np.fft.fft(y, axis=2)[:, :, lines]
    n = U.shape[0]
    Um, Ym = U.mean(0), Y.mean(1)
    H = Ym / Um
    vu = np.var(U, axis=0, ddof=1) / n
    vy = np.var(Y, axis=1, ddof=1) / n
    cyu = np.array([((Y[i] - Ym[i]) * np.conj(U - Um)).sum(0) / (n - 1) / n for i in range(3)])
    var = np.maximum((vy + np.abs(H) ** 2 * vu - 2 * np.real(np.conj(H) * cyu)) / np.abs(Um) ** 2, 0)
    w = 2 * np.pi * np.arange(41, 308) * fs / period
    s = 1j * w
    scale = np.abs(H).copy()
    for i in range(3):
        for k in range(len(w)):
            near = np.abs(np.log10(w / w[k])) <= 0.1
            scale[i, k] = max(scale[i, k], 0.1 * np.abs(H[i, near]).max(), 3 * np.sqrt(var[i, k]))
    floor = np.sqrt(np.mean(var / scale ** 2))

    def figure(model):
        return np.sqrt(np.mean(np.mean(np.abs(H - model) ** 2 / scale ** 2, axis=1)))

    def solve(columns):
        B = np.array(columns).T
        model = np.zeros_like(H)
        for i in range(3):
            A = B / scale[i][:, None]
            b = H[i] / scale[i]
            x = np.linalg.lstsq(np.vstack([A.real, A.imag]), np.concatenate([b.real, b.imag]), rcond=None)[0]
            model[i] = B @ x
        return model

    def vector_fit(N, iterations=30):
        wp = np.linspace(w[0], w[-1], N)
        poles = -wp / 100 + 1j * wp
        W = 1 / scale
        for _ in range(iterations):
            basis = []
            for p in poles:
                a, b = 1 / (s - p), 1 / (s - np.conj(p))
                basis += [a + b, 1j * (a - b)]
            B = np.array(basis).T
            E = np.array([np.ones_like(s), s]).T
            nb, ne = B.shape[1], E.shape[1]
            blocks, rhs = [], []
            for i in range(3):
                A = np.zeros((len(s), 3 * (nb + ne) + nb), complex)
                A[:, i * (nb + ne):i * (nb + ne) + nb] = B * W[i][:, None]
                A[:, i * (nb + ne) + nb:(i + 1) * (nb + ne)] = E * W[i][:, None]
                A[:, 3 * (nb + ne):] = -(H[i] * W[i])[:, None] * B
                blocks.append(A)
                rhs.append(H[i] * W[i])
            A, b = np.vstack(blocks), np.concatenate(rhs)
            x = np.linalg.lstsq(np.vstack([A.real, A.imag]), np.concatenate([b.real, b.imag]), rcond=None)[0]
            c = x[3 * (nb + ne):]
            Ar, br = np.zeros((2 * N, 2 * N)), np.zeros(2 * N)
            for k, p in enumerate(poles):
                Ar[2 * k:2 * k + 2, 2 * k:2 * k + 2] = [[p.real, p.imag], [-p.imag, p.real]]
                br[2 * k] = 2
            z = np.linalg.eigvals(Ar - np.outer(br, c))
            z = np.where(z.real > 0, -z.real + 1j * z.imag, z)  # flip unstable poles
            upper = z[z.imag > 0]
            if len(upper) < N:  # real poles: make them a lightly damped pair at the band's bottom
                extra = -np.abs(z[np.abs(z.imag) < 1e-9][:N - len(upper)]) + 1j * w[0]
                upper = np.concatenate([upper, extra])
            poles = upper[:N]
        basis = []
        for p in poles:
            a, b = 1 / (s - p), 1 / (s - np.conj(p))
            basis += [a + b, 1j * (a - b)]
        return solve(basis + [np.ones_like(s), s]), poles

    def real_modes(poles, residual_terms):
        cols = []
        for p in poles:
            wn, zeta = abs(p), -p.real / abs(p)
            cols.append(s ** 2 / (s ** 2 + 2 * zeta * wn * s + wn ** 2))
        if residual_terms:
            cols += [np.ones_like(s), s ** 2]
        return solve(cols)

    print(f"noise floor {100 * floor:.3f} %  (1.5x: {150 * floor:.2f} %)")
    print("pole pairs | free (complex residues) | real residues + d + e s^2 | real, no residual terms | poles (Hz)")
    for N in [4, 6, 8, 10, 12, 16, 24, 32, 40]:
        model, poles = vector_fit(N)
        hz = " ".join(f"{abs(p) / (2 * np.pi):.2f}" for p in sorted(poles, key=abs)) if N <= 24 else ""
        print(f"{N:10d} | {100 * figure(model):22.2f} % | {100 * figure(real_modes(poles, True)):24.2f} % | "
              f"{100 * figure(real_modes(poles, False)):21.2f} % | {hz}")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: f16-rational-bound.py F16_LEVEL_CSV (e.g. ../shared/real-data/f16_gvt/f16_fullmsine_level1.csv)")
    main(sys.argv[1])
