"""Writes one run, read from forcemap's plain CSV export, in the forms test labs have, with
independent tools: ASAM MDF4 by asammdf, NI TDMS by npTDMS, and a CSV in a lab dialect by the
csv module. Python is for this third-party check only.

    measurement_files.py PLAIN_CSV OUT_DIR

Writes OUT_DIR/run.mf4 (one channel group, asammdf's `time` master, `step` as int64),
OUT_DIR/run_two_groups.mf4 (the channels split over two channel groups),
OUT_DIR/run.tdms (channels with a `time_s` channel, over several segments),
OUT_DIR/run_wf.tdms (no time channel: wf_start_offset/wf_increment on each channel) and
OUT_DIR/run_semicolon.csv (UTF-8 byte-order mark, `;`, decimal commas, a units row, CRLF, and
a last line cut short as by an interrupted recording). Prints the truncated line's number.
"""
import csv
import sys
from pathlib import Path

import numpy as np
from asammdf import MDF, Signal
from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

UNITS = {"time_s": "s", "step": "-", "frequency_hz": "Hz"}


def unit(name):
    if name in UNITS:
        return UNITS[name]
    if name.endswith("_mps2"):
        return "m/s^2"
    return {"_m": "m", "_n": "N"}[name[name.rfind("_"):]]


def main():
    plain, out = Path(sys.argv[1]), Path(sys.argv[2])
    with plain.open(newline="") as f:
        rows = list(csv.reader(f))
    header, data = rows[0], rows[1:]
    cols = {name: np.array([float(r[i]) for r in data]) for i, name in enumerate(header)}
    time = cols["time_s"]
    channels = [n for n in header if n != "time_s"]

    # MDF4: one group, the time stamps as its master channel.
    mdf = MDF(version="4.10")
    signals = []
    for n in channels:
        samples = cols[n].astype(np.int64) if n == "step" else cols[n]
        signals.append(Signal(samples, time, name=n, unit=unit(n)))
    mdf.append(signals, comment="forcemap run")
    mdf.save(out / "run.mf4", overwrite=True)
    # The same channels over two groups (two time bases to forcemap): refused.
    mdf = MDF(version="4.10")
    mdf.append(signals[:3])
    mdf.append(signals[3:])
    mdf.save(out / "run_two_groups.mf4", overwrite=True)

    # TDMS with a time channel, written in three segments.
    cuts = np.array_split(np.arange(len(time)), 3)
    with TdmsWriter(out / "run.tdms") as w:
        for k, idx in enumerate(cuts):
            objs = [ChannelObject("run", n, cols[n][idx]) for n in header]
            if k == 0:
                objs = [RootObject({"title": "forcemap run"}), GroupObject("run")] + objs
            w.write_segment(objs)

    # TDMS with waveform timing instead of a time channel.
    increment = float(np.median(np.diff(time)))
    props = {"wf_start_offset": float(time[0]), "wf_increment": increment, "unit_string": ""}
    with TdmsWriter(out / "run_wf.tdms") as w:
        w.write_segment(
            [RootObject(), GroupObject("run")]
            + [ChannelObject("run", n, cols[n], properties={**props, "unit_string": unit(n)})
               for n in channels]
        )

    # A lab dialect of the CSV: the same cells, decimal commas.
    with (out / "run_semicolon.csv").open("w", encoding="utf-8-sig", newline="") as f:
        f.write(";".join(header) + "\r\n")
        f.write(";".join(unit(n) for n in header) + "\r\n")
        for r in data:
            f.write(";".join(c.replace(".", ",") for c in r) + "\r\n")
        # An interrupted recording: the next sample's line, cut after its third cell.
        f.write(";".join(data[-1][:3]).replace(".", ","))
    print(len(data) + 3)


if __name__ == "__main__":
    main()
