"""Writes the seeds of the tdms_read, mdf_read and csv_dialect fuzz targets with independent
tools (asammdf, npTDMS): `python gen_measurement_seeds.py seeds`. Small files of a short rig run
(two steps of 12 samples) in the forms the readers meet."""
import sys
from pathlib import Path

import numpy as np
from asammdf import MDF, Signal
from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

out = Path(sys.argv[1])
fs, n = 100.0, 12
t = np.arange(2 * n) / fs
step = np.repeat([0, 1], n)
freq = np.repeat([2.0, 3.0], n)
base = 0.006 * np.sin(2 * np.pi * freq * t)
rel = 0.001 * np.sin(2 * np.pi * freq * t + 0.3)
acc = -(2 * np.pi * freq) ** 2 * base
cols = {"time_s": t, "step": step, "frequency_hz": freq, "base_displacement_m": base,
        "relative_displacement_m": rel, "mass_acceleration_mps2": acc}

d = out / "mdf_read"
d.mkdir(parents=True, exist_ok=True)
for version, name in [("4.10", "asammdf_410.mf4"), ("4.20", "asammdf_420.mf4")]:
    m = MDF(version=version)
    m.append([Signal(cols[k], t, name=k) for k in cols if k != "time_s"])
    m.save(d / name, overwrite=True)
m = MDF(version="4.10")
m.append([Signal(cols[k], t, name=k) for k in cols if k != "time_s"])
m.save(d / "asammdf_deflate.mf4", overwrite=True, compression=1)

d = out / "tdms_read"
d.mkdir(parents=True, exist_ok=True)
with TdmsWriter(d / "nptdms_time.tdms") as w:
    w.write_segment([RootObject(), GroupObject("run")]
                    + [ChannelObject("run", k, v[:n]) for k, v in cols.items()])
    w.write_segment([ChannelObject("run", k, v[n:]) for k, v in cols.items()])
with TdmsWriter(d / "nptdms_wf.tdms") as w:
    props = {"wf_start_offset": 0.0, "wf_increment": 1 / fs}
    w.write_segment([RootObject(), GroupObject("run")]
                    + [ChannelObject("run", k, v.astype(np.float32) if k.endswith("_m") else v,
                                     properties=props)
                       for k, v in cols.items() if k != "time_s"])

d = out / "csv_dialect"
d.mkdir(parents=True, exist_ok=True)
names = list(cols)
rows = [[repr(float(cols[k][i])) for k in names] for i in range(len(t))]
units = ["s", "-", "Hz", "m", "m", "m/s^2"]
(d / "plain.csv").write_text("\n".join([",".join(names)] + [",".join(r) for r in rows]) + "\n")
(d / "semicolon_comma_units_bom_crlf.csv").write_bytes(
    ("\ufeff" + "\r\n".join([";".join(names), ";".join(units)]
                            + [";".join(c.replace(".", ",") for c in r) for r in rows])
     + "\r\n" + "0,25;1;3").encode())
(d / "tab_truncated.csv").write_text(
    "\n".join(["\t".join(names)] + ["\t".join(r) for r in rows]) + "\n0.25\t1\t3.0\t0.00")
