#!/usr/bin/env python3
"""Writes a CSV export's run as an ASAM MDF4 file (asammdf) and an NI TDMS file (npTDMS), its
channels named as the export names its columns: the throughput benchmark's inputs in the
formats test labs record. Python is for writing them with third-party tools only.

Usage: export_as_measurement_files.py IN.csv OUT_STEM
  Writes OUT_STEM.mf4 (one channel group, asammdf's `time` master from time_s, every other
  column a float64 channel) and OUT_STEM.tdms (group `rig`, every column a float64 channel
  including time_s, in segments of 100 000 rows).
  export_as_measurement_files.py rig200.csv rig200   # 131 MB each from the 246 MB export
"""
import sys

import numpy as np
from asammdf import MDF, Signal
from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

ROWS_A_SEGMENT = 100_000


def main():
    src, out = sys.argv[1], sys.argv[2]
    with open(src) as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(src, delimiter=",", skiprows=1, ndmin=2)
    time = data[:, header.index("time_s")]

    mdf = MDF(version="4.10")
    signals = [Signal(data[:, i], time, name=n) for i, n in enumerate(header) if n != "time_s"]
    mdf.append(signals, acq_name="rig")
    mdf.save(out + ".mf4", overwrite=True)

    cuts = np.array_split(np.arange(len(time)), max(1, len(time) // ROWS_A_SEGMENT))
    with TdmsWriter(out + ".tdms") as w:
        for k, rows in enumerate(cuts):
            objects = [ChannelObject("rig", n, data[rows, i]) for i, n in enumerate(header)]
            if k == 0:
                objects = [RootObject({}), GroupObject("rig")] + objects
            w.write_segment(objects)


if __name__ == "__main__":
    main()
