#!/usr/bin/env python3
"""Writes P_axis.csv, the bundled 'measured' response of the two-mass axis
(samples/mechanical-loop.sh): M q'' + D q' + K q = B_w i solved in the frequency
domain with the true values below (not the description's), two flexible modes the
description lacks, and 0.5 % complex Gaussian noise per entry.  Standard library only;
the file it writes is committed, so running this again must reproduce it byte for byte."""
import math
import random

MC, ML, K, C, CG, KF = 2.0, 6.5, 1.6e5, 55.0, 24.0, 12.0
MODES = ((900.0, 0.02, 0.15, 0.25), (2200.0, 0.01, 0.1, -0.2))  # rad/s, zeta, shape (x_m, x_l)
NOISE = 0.005
SEED = 20261129


def response(w):
    jw = 1j * w
    z11 = K - w * w * MC + jw * (CG + C)
    z12 = -K - jw * C
    z22 = K - w * w * ML + jw * C
    det = z11 * z22 - z12 * z12
    q = [z22 * KF / det, -z12 * KF / det]  # Cramer's rule, B_w = (k_f, 0)
    for wm, z, pm, pl in MODES:
        eta = pm * KF / (wm ** 2 - w * w + 2 * jw * z * wm)
        q = [q[0] + pm * eta, q[1] + pl * eta]
    return q


def main():
    rng = random.Random(SEED)
    n, lo, hi = 200, math.log10(5), math.log10(4000)
    with open("P_axis.csv", "w") as f:
        f.write("# The two-mass axis of two_mass_axis.json as a lab would measure it: its response from\n")
        f.write("# M q'' + D q' + K q = B_w i solved in the frequency domain (the true values below, not\n")
        f.write("# the description's), with two flexible modes the description lacks, and 0.5 % complex\n")
        f.write("# Gaussian noise per entry (relative, Python random.Random(20261129)).\n")
        f.write("# truth: m_carriage_kg 2, m_load_kg 6.5, k_coupling_N_per_m 160000, c_coupling_Ns_per_m 55,\n")
        f.write("#   c_guide_Ns_per_m 24, k_f_N_per_A 12; modes 900 rad/s zeta 0.02 shape (0.15, 0.25) and\n")
        f.write("#   2200 rad/s zeta 0.01 shape (0.1, -0.2) (1/kg^0.5; a mode and its negative are the same)\n")
        f.write("# outputs: enc,load\n# inputs: i\nfreq_hz,P_enc_i_re,P_enc_i_im,P_load_i_re,P_load_i_im\n")
        for i in range(n):
            x = 10 ** (lo + (hi - lo) * i / (n - 1))
            p = [v * (1 + NOISE * complex(rng.gauss(0, 1), rng.gauss(0, 1)) / math.sqrt(2)) for v in response(x)]
            f.write("%.17g,%.17g,%.17g,%.17g,%.17g\n" % (x / 2 / math.pi, p[0].real, p[0].imag, p[1].real, p[1].imag))


if __name__ == "__main__":
    main()
