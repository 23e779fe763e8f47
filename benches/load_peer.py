#!/usr/bin/env python3
"""How long Python's fastest common loader takes to read a file into columns of numbers: for a
CSV export `polars.read_csv` where polars is installed, else `numpy.loadtxt`; for an ASAM MDF4
file asammdf (every channel's samples), for an NI TDMS file npTDMS (every channel's data).
`forcemap bench identify --python PY` runs it to compare identify's whole run against loading
alone; it prints one JSON
object: the loader, the wall and CPU seconds of each repeat, the rows loaded and the peak
resident memory of the process (VmHWM: the peak of this program's own address space, where
ru_maxrss may count the memory of the process that started it).

Usage: load_peer.py FILE [--repeats N]
"""
import argparse
import json
import time


def loader(path):
    with open(path, "rb") as f:
        head = f.read(8)
    if head in (b"MDF     ", b"UnFinMF "):
        import asammdf

        def load_mdf(p):
            with asammdf.MDF(p) as mdf:
                return max(len(s.samples) for s in mdf.iter_channels())

        return f"asammdf {asammdf.__version__}", load_mdf
    if head.startswith(b"TDSm"):
        import nptdms

        def load_tdms(p):
            f = nptdms.TdmsFile.read(p)
            return max(len(c[:]) for g in f.groups() for c in g.channels())

        return f"npTDMS {nptdms.__version__}", load_tdms
    try:
        import polars

        return f"polars {polars.__version__}", lambda p: polars.read_csv(p).height
    except ImportError:
        import numpy

        def load(p):
            return numpy.loadtxt(p, delimiter=",", skiprows=1).shape[0]

        return f"numpy {numpy.__version__} loadtxt", load


def peak_bytes():
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("file")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    name, load = loader(args.file)
    load_s, load_cpu_s, rows = [], [], 0
    for _ in range(args.repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        rows = load(args.file)
        load_s.append(time.perf_counter() - t0)
        load_cpu_s.append(time.process_time() - c0)
    print(json.dumps({
        "loader": name,
        "load_s": load_s,
        "load_cpu_s": load_cpu_s,
        "rows": rows,
        "peak_bytes": peak_bytes(),
    }))


if __name__ == "__main__":
    main()
