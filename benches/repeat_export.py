#!/usr/bin/env python3
"""Writes a long rig CSV export by repeating a short one: the throughput benchmark's input.

Copy k (0, 1, ...) of the rows has its step numbered on after copy k - 1 and its time moved by k
times the run's length (last time plus one interval, from the first time), so the file is one
run of contiguous steps with strictly increasing time, as the CSV contract asks. Every other
cell is copied as written. Standard library only.

Usage: repeat_export.py IN.csv COPIES OUT.csv
  forcemap simulate --snr-db 40 --csv rig.csv    # 15 600 rows, 1.8 MB
  repeat_export.py rig.csv 131 rig200.csv        # 2 043 600 rows, 238 MB
"""
import sys


def main():
    src, copies, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    with open(src) as f:
        header = f.readline()
        rows = [line.rstrip("\n").split(",", 2) for line in f if line.strip()]
    names = header.rstrip("\n").split(",")
    if names[:2] != ["time_s", "step"]:
        sys.exit(f"{src}: expected the columns time_s, step first")
    times = [float(r[0]) for r in rows]
    steps = [int(r[1]) for r in rows]
    interval_s = times[1] - times[0]
    run_s = times[-1] + interval_s - times[0]
    step_count = max(steps) - min(steps) + 1
    with open(out, "w") as f:
        f.write(header)
        for k in range(copies):
            shift_s, shift_steps = k * run_s, k * step_count
            f.writelines(
                f"{t + shift_s!r},{s + shift_steps},{r[2]}\n"
                for t, s, r in zip(times, steps, rows)
            )


if __name__ == "__main__":
    main()
