#!/usr/bin/env python3
"""Stepped sine vs sine sweep (linear, log) vs band random on the paper's rig (Coulomb truth),
same total duration (130 s of identification data), through the command: `forcemap simulate`
writes each run, `forcemap identify --json` identifies it. Prints the mean |error| [%] of k, c,
F_d over the seeds and the mean reported std [%], per SNR.

    python3 eval/sweep_compare.py FORCEMAP_BINARY [SEEDS] [SNR_DB ...]
"""
import json
import subprocess
import sys
import tempfile
from pathlib import Path

TRUTH = {"k": 6380.0, "c": 184.0, "fd": 12.3}
# (label, simulate flags, identify flags)
CASES = [
    ("stepped fd-multi", ["--no-random"], []),
    ("sweep linear fd-multi", ["--excitation", "sweep", "--sweep-kind", "linear", "--no-random"], []),
    ("sweep log fd-multi", ["--excitation", "sweep", "--sweep-kind", "log", "--no-random"], []),
    ("sweep linear td-all", ["--excitation", "sweep", "--sweep-kind", "linear", "--no-random"],
     ["--method", "td-all"]),
    ("stepped td-all", ["--no-random"], ["--method", "td-all"]),
    ("random td-all", ["--excitation", "random"], ["--method", "td-all"]),
]


def run(binary, args):
    out = subprocess.run([binary] + args, capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"{' '.join(args)}: {out.stderr}")
    return out.stdout


def main():
    binary = sys.argv[1]
    seeds = int(sys.argv[2]) if len(sys.argv) > 2 else 5
    snrs = [s for s in sys.argv[3:]] or ["none", "40", "30"]
    with tempfile.TemporaryDirectory() as tmp:
        csv = str(Path(tmp) / "run.csv")
        print(f"| case | SNR | k err % | c err % | fd err % | k std % | c std % | fd std % |")
        print("|---|---|---|---|---|---|---|---|")
        for label, sim, ident in CASES:
            for snr in snrs:
                noise = [] if snr == "none" else ["--snr-db", snr]
                errs = {p: [] for p in TRUTH}
                stds = {p: [] for p in TRUTH}
                for seed in range(1, (1 if snr == "none" else seeds) + 1):
                    run(binary, ["simulate", "--system", "rig", "--seed", str(seed), "--csv", csv]
                        + sim + noise)
                    j = json.loads(run(binary, ["identify", csv, "--model", "coulomb",
                                                "--mass-kg", "36", "--json"] + ident))
                    for p in j["parameters"]:
                        t = TRUTH[p["name"]]
                        errs[p["name"]].append(abs(p["value"] / t - 1) * 100)
                        stds[p["name"]].append(p["std"] / t * 100)
                mean = lambda v: sum(v) / len(v)
                cells = [f"{mean(errs[p]):.2f}" for p in TRUTH] + [f"{mean(stds[p]):.2f}" for p in TRUTH]
                print(f"| {label} | {snr} | " + " | ".join(cells) + " |", flush=True)


main()
