#!/usr/bin/env python3
"""The numpy peer of `forcemap identify --method fd --model coulomb` on a rig CSV export.

What a user would write with numpy: read the CSV, fit the first harmonic of the relative
displacement and of the mass acceleration on the second half of each sine step (least squares
on cos, sin and a constant), and solve the paper's first-harmonic force-state equations
G = k X + c jw X + fd (4/pi) jw X / |w X| (G = -m A, the element force) over the steps for
k, c, fd. `forcemap bench identify` runs it and compares medians; it prints one JSON object:
parse and fit times in seconds per repeat (wall, and CPU time of the process), and the
parameters.

Usage: numpy_peer.py FILE --mass-kg M [--repeats N]
"""
import argparse
import json
import time

import numpy as np


def parse(path):
    with open(path) as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    return {name: data[:, i] for i, name in enumerate(header)}


def fit(cols, mass_kg):
    rows, rhs = [], []
    t, step, freq = cols["time_s"], cols["step"], cols["frequency_hz"]
    for s in np.unique(step):
        sel = step == s
        f = freq[sel][0]
        if not f > 0:
            continue  # a random record: validation, not fitting
        ts = t[sel]
        half = ts.size // 2
        ts = ts[half:]
        w = 2 * np.pi * f
        basis = np.column_stack([np.cos(w * ts), np.sin(w * ts), np.ones_like(ts)])
        x = cols["relative_displacement_m"][sel][half:]
        a = cols["mass_acceleration_mps2"][sel][half:]
        (xc, xs, _), *_ = np.linalg.lstsq(basis, x, rcond=None)
        (ac, as_, _), *_ = np.linalg.lstsq(basis, a, rcond=None)
        big_x = xc - 1j * xs
        big_g = -mass_kg * (ac - 1j * as_)
        v = 1j * w * big_x
        row = np.array([big_x, v, 4 / np.pi * v / abs(v)])
        rows += [row.real, row.imag]
        rhs += [big_g.real, big_g.imag]
    theta, *_ = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)
    return theta


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("file")
    ap.add_argument("--mass-kg", type=float, required=True)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    parse_s, fit_s, parse_cpu_s, fit_cpu_s = [], [], [], []
    for _ in range(args.repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        cols = parse(args.file)
        t1, c1 = time.perf_counter(), time.process_time()
        theta = fit(cols, args.mass_kg)
        t2, c2 = time.perf_counter(), time.process_time()
        parse_s.append(t1 - t0)
        fit_s.append(t2 - t1)
        parse_cpu_s.append(c1 - c0)
        fit_cpu_s.append(c2 - c1)
    print(json.dumps({
        "parse_s": parse_s,
        "fit_s": fit_s,
        "parse_cpu_s": parse_cpu_s,
        "fit_cpu_s": fit_cpu_s,
        "k": theta[0],
        "c": theta[1],
        "fd": theta[2],
        "rows": int(next(iter(cols.values())).size),
    }))


if __name__ == "__main__":
    main()
