#!/usr/bin/env python3
"""Writes a closed-loop log of a positioning axis with friction (samples/friction-loop.sh):
a carriage on a ball screw, m x'' = k_f i - c x' - F_c sign(x') - F_0 (Coulomb friction: at
rest it holds any net force up to F_c, the axis sticks), integrated at 100 substeps per
sample (semi-implicit Euler; a velocity that would change sign within a substep stops at
zero), under a discrete PD controller on the quantised encoder
(1 kHz, the current held between samples) tracking a reference trajectory; the logged
current carries a current sensor's Gaussian noise.  The true values below are not the
description's (mechanical/ball_screw_axis.json: mass 3 kg, viscous 10 N s/m, no friction,
no offset).  Standard library only; a second implementation of the simulator the tests
use (tests/support/friction_axis.h), with its own noise sequence.

usage: make_axis_log.py OUT.csv [--one-way]   (--one-way: a motion that never reverses)"""
import math
import random
import sys

M, C, FC, F0, KF = 4.2, 35.0, 6.5, 2.8, 10.0
RATE, SECONDS, ENCODER, CURRENT_NOISE, SEED = 1000.0, 20.0, 1e-6, 0.005, 20261130


def reference(t, one_way):
    if one_way:
        return 0.05 * t + 0.01 * math.sin(2 * math.pi * 0.7 * t)
    return 0.1 * math.sin(2 * math.pi * 0.4 * t) + 0.03 * math.sin(2 * math.pi * 1.3 * t + 1.0)


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    one_way = "--one-way" in sys.argv[2:]
    rng = random.Random(SEED)
    ts = 1.0 / RATE
    wc = 2 * math.pi * 30.0
    kp, kd = M * wc * wc, 2 * 0.7 * M * wc
    alpha = math.exp(-2 * math.pi * 300.0 * ts)
    x, v, e_prev, d_filt = reference(0.0, one_way), 0.0, 0.0, 0.0

    with open(sys.argv[1], "w") as out:
        out.write("t,r,i,enc\n")
        for k in range(int(round(SECONDS * RATE))):
            t = k * ts
            enc = round(x / ENCODER) * ENCODER
            r = reference(t, one_way)
            err = r - enc
            d_filt = alpha * d_filt + (1 - alpha) * (0.0 if k == 0 else (err - e_prev) / ts)
            e_prev = err
            current = (kp * err + kd * d_filt + 2.0) / KF
            out.write(f"{t:.6f},{r:.9g},{current + CURRENT_NOISE * rng.gauss(0.0, 1.0):.9g},{enc:.9g}\n")
            h = ts / 100
            for _ in range(100):
                applied = KF * current - C * v - F0
                if v == 0.0:
                    v_new = 0.0 if abs(applied) <= FC else h * (applied - math.copysign(FC, applied)) / M
                else:
                    v_new = v + h * (applied - math.copysign(FC, v)) / M
                    if v_new * v < 0.0:
                        v_new = 0.0
                x += 0.5 * h * (v + v_new)
                v = v_new


if __name__ == "__main__":
    main()
