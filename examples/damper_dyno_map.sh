#!/usr/bin/env bash
# A damper dyno's own files read as they lie, through a channel map: twelve sine tests (1-8 Hz,
# 5-20 mm strokes), one text file per test with the dyno's preamble, whitespace between the
# columns, position in mm and fixture acceleration in g; `forcemap info` shows how they are read
# and cut, `forcemap identify --model damper` fits the damper and prints its dynamic stiffness.
# The files are made here from forcemap's simulated dyno (`forcemap simulate --system
# damper-dyno`: preload 150 N, gas spring 2000 N/m, rebound 2500 / compression 1000 N s/m,
# friction 40 N, fixture 0.8 kg), rewritten as a bench writes them.
#
#   bash examples/damper_dyno_map.sh [SCRATCH_DIR]   # FORCEMAP=path/to/forcemap to choose the binary
#
# Exits non-zero when an expected line of the output is missing or a parameter is off its truth.
set -euo pipefail

source "$(dirname "$0")/lib.bash"
cd "$WORK"

say "1. The dyno's run (simulated, 40 dB SNR, seed 1) as forcemap's CSV"
run simulate --system damper-dyno --snr-db 40 --csv dyno.csv
head -n 2 dyno.csv

say "2. Rewritten as the dyno writes it: one file per sine test, a preamble, no header, mm and g"
# dyno.csv: time_s, step, frequency_hz, relative_displacement_m, mass_acceleration_mps2, force_n.
# Each test's file: 4 preamble lines, then time [s] from the test's start, position [mm],
# force [N], fixture acceleration [g] and the oil temperature [C], which forcemap does not need.
rm -rf dyno_export && mkdir dyno_export
awk -F, 'NR > 1 {
    file = sprintf("dyno_export/test%02d_%gHz.dat", $2, $3)
    if (file != last) {
        t0 = $1; last = file
        print "Damper dyno DD-2 export" > file
        printf "Specimen: twin-tube damper 7; test %d: sine %g Hz\n", $2, $3 > file
        print "Sample rate: 1000 Hz" > file
        print "Time[s]  Position[mm]  Force[N]  Accel[g]  OilTemp[C]" > file
    }
    printf "%.4f  %.5f  %.3f  %.6f  %.2f\n", $1 - t0, $4 * 1000, $6, $5 / 9.80665, 21.5 + 0.02 * $1 > file
}' dyno.csv
ls dyno_export
head -n 6 dyno_export/test00_1Hz.dat

say "3. The channel map: which column is which forcemap channel, and in which unit"
cat > dyno_map.yaml <<'YAML'
# DD-2 exports: 4 preamble lines, then whitespace-separated columns
# time [s], position [mm], force [N], fixture acceleration [g], oil temperature [C].
table: {skip_lines: 4, header: false}
channels:
  time_s:                  {channel: 1, unit: s}
  relative_displacement_m: {channel: 2, unit: mm}
  force_n:                 {channel: 3, unit: N}
  mass_acceleration_mps2:  {channel: 4, unit: g}
YAML
cat dyno_map.yaml

say "4. What forcemap finds in the files (columns, units, the record of each test)"
run info dyno_export/test00_1Hz.dat dyno_export/test11_8Hz.dat --channels dyno_map.yaml | tee info.txt
run info 'dyno_export/*.dat' --channels dyno_map.yaml --plot drive_plots > info_all.txt
grep -c ' sine ' info_all.txt | sed 's/$/ sine records found in the 12 files/'

say "5. Identify the damper from the twelve files together (the fixture's mass identified as m)"
# A quoted pattern is expanded by forcemap, in name order: the tests are numbered on from file to file.
run identify 'dyno_export/*.dat' --channels dyno_map.yaml --model damper --plot plots | grep -v '^notice' | tee identify.txt
ls plots

say "Checks"
expect info.txt 'column 2 +-> relative_displacement_m \(mm -> m' "position read in mm"
expect info.txt 'column 4 +-> mass_acceleration_mps2 \(g -> m/s\^2' "acceleration read in g"
expect info.txt 'setup: +element' "an element test"
expect identify.txt 'model damper by ' "the damper model identified"
expect identify.txt '^dynamic stiffness K\* = G_1 / X_1' "the dynamic stiffness table"
expect identify.txt '^ +11 +8\.000 ' "the table's row of the last test (8 Hz, 20 mm)"
near identify.txt offset 150 1
near identify.txt k 2000 2
near identify.txt c 1750 1
near identify.txt ca 750 1
near identify.txt fd 40 2
near identify.txt m 0.8 3
test -s plots/dynamic_stiffness.svg && echo "ok: plots/dynamic_stiffness.svg written"
echo "damper_dyno_map: all checks passed"
