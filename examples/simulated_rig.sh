#!/usr/bin/env bash
# The paper's suspension rig, simulated and identified: a test-bench CSV export of ten
# stepped-sine steps (1.6-3.4 Hz, 6 mm) and two band-random validation records at 40 dB SNR,
# the Coulomb model fitted to it, and the node graph that does the same live.
#
#   bash examples/simulated_rig.sh [SCRATCH_DIR]     # FORCEMAP=path/to/forcemap to choose the binary
#
# Exits non-zero when an expected line of the output is missing or a parameter is off its truth.
set -euo pipefail

source "$(dirname "$0")/lib.bash"
cd "$WORK"

say "1. Simulate the rig to a test-bench CSV export (seed 1)"
run simulate --snr-db 40 --csv rig.csv
head -n 3 rig.csv

say "2. Identify the element: k, c and fd of the Coulomb model, the rig's mass given"
run identify rig.csv --model coulomb --mass-kg 36 --plot plots | tee identify.txt
ls plots

say "3. The node graph that plays the same run live (its commands only: --dry-run)"
run launch "$REPO/launch_configs/rig_sim.launch.yaml" --dry-run | tee launch.txt

say "Checks"
expect identify.txt '^k +[-0-9.e+]+ ' "k is printed"
expect identify.txt '^c +[-0-9.e+]+ ' "c is printed"
expect identify.txt '^fd +[-0-9.e+]+ ' "fd is printed"
expect identify.txt 'validation on random record 10: NMSE of mass acceleration' "the validation NMSE of record 10"
expect identify.txt 'validation on random record 11: NMSE of mass acceleration' "the validation NMSE of record 11"
near identify.txt k 6380 1
near identify.txt c 184 1
near identify.txt fd 12.3 1
expect launch.txt 'node sensor .*-p source:=sim' "the graph's simulated sensor node"
expect launch.txt 'node identifier .*model:=coulomb' "the graph's identifier node"
test -s plots/force_state.svg && echo "ok: plots/force_state.svg written"
echo "simulated_rig: all checks passed"
