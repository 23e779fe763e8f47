"""Writes one element test, read from a plain CSV of its samples (time_s,
relative_displacement_m, force_n), as a bench's own measurement files would hold it: its own
channel names and units, written by independent tools. Python is for this third-party check
only.

    bench_files.py PLAIN_CSV OUT_DIR

Writes OUT_DIR/bench.mf4 (asammdf: one channel group "Dyno" with its time master, `Act_Pos`
in mm, `Load` in kN, `Oil_Temp` in degC, units in the channels' metadata) and
OUT_DIR/bench.tdms (npTDMS: group "Dyno", channels `Time` [s], `Act_Pos` [mm], `Load` [kN]
and `Supply` [V], units as `unit_string`, written in four segments).
"""
import csv
import sys
from pathlib import Path

import numpy as np
from asammdf import MDF, Signal
from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter


def main():
    plain, out = Path(sys.argv[1]), Path(sys.argv[2])
    with plain.open(newline="") as f:
        rows = list(csv.reader(f))
    header, data = rows[0], rows[1:]
    cols = {name: np.array([float(r[i]) for r in data]) for i, name in enumerate(header)}
    time = cols["time_s"]
    position_mm = cols["relative_displacement_m"] * 1e3
    load_kn = cols["force_n"] * 1e-3
    temperature = np.full_like(time, 41.5)

    mdf = MDF(version="4.10")
    mdf.append(
        [
            Signal(position_mm, time, name="Act_Pos", unit="mm"),
            Signal(load_kn, time, name="Load", unit="kN"),
            Signal(temperature, time, name="Oil_Temp", unit="degC"),
        ],
        acq_name="Dyno",
        comment="damper dyno",
    )
    mdf.save(out / "bench.mf4", overwrite=True)

    cuts = np.array_split(np.arange(len(time)), 4)
    with TdmsWriter(out / "bench.tdms") as w:
        for k, idx in enumerate(cuts):
            objs = [
                ChannelObject("Dyno", "Time", time[idx], properties={"unit_string": "s"}),
                ChannelObject("Dyno", "Act_Pos", position_mm[idx], properties={"unit_string": "mm"}),
                ChannelObject("Dyno", "Load", load_kn[idx], properties={"unit_string": "kN"}),
                ChannelObject("Dyno", "Supply", np.full(len(idx), 24.0), properties={"unit_string": "V"}),
            ]
            if k == 0:
                objs = [RootObject({"title": "damper dyno"}), GroupObject("Dyno")] + objs
            w.write_segment(objs)


if __name__ == "__main__":
    main()
