#!/usr/bin/env bash
# A real MR damper's sine tests (data/real/mr_damper_utfsm: headerless text in mm, one test per
# file, as the lab wrote them): what forcemap finds in them, the damper model fitted to four tests
# and checked on two held-out ones, and the gap diagnosis of a linear model, which names the
# damper's yield (Coulomb-like friction) as what the linear model misses.
#
#   bash examples/real_damper.sh [SCRATCH_DIR]       # FORCEMAP=path/to/forcemap to choose the binary
#
# Exits non-zero when an expected line of the output is missing.
set -euo pipefail

source "$(dirname "$0")/lib.bash"
# The data are read where they lie in the repository; what the example writes goes to $WORK.
cd "$REPO"

D=data/real/mr_damper_utfsm
FIT=("$D/2mm5Hz0A.txt" "$D/25mm0x1Hz0A.txt" "$D/25mm0x25Hz0A.txt" "$D/25mm0x5Hz0A.txt")
HELD=(--validate "$D/5mm3Hz0A.txt" --validate "$D/10mm1Hz0A.txt")

say "1. The channel map of the lab's files: time [s], displacement [mm], velocity, force [N]"
cat "$D/map.yaml"

say "2. What forcemap finds in the six tests (columns, units, one sine record per file)"
run info "$D"/*.txt --channels "$D/map.yaml" --plot "$WORK/drive_plots" | grep -v '^notice' | tee "$WORK/info.txt"

say "3. The damper model fitted to four tests, predicting the force of two held-out tests"
# An MR damper's yield is no term of the damper model: identify warns that the form is wrong and
# picks the estimator that predicts left-out tests best; the held-out NMSE says how well it does.
run identify "${FIT[@]}" --channels "$D/map.yaml" --model damper "${HELD[@]}" \
    | grep -v '^notice' | tee "$WORK/identify.txt"

say "4. What a linear model misses, and which effect closes the gap (the same tests)"
run diagnose "${FIT[@]}" --channels "$D/map.yaml" --model linear "${HELD[@]}" \
    | grep -v '^notice' | tee "$WORK/diagnose.txt"

say "Checks"
expect "$WORK/info.txt" '^ +0 +sine ' "sine records found"
expect "$WORK/identify.txt" '^held out: .*5mm3Hz0A\.txt record 0: force NMSE [0-9.]+ %' "held-out test 5 mm 3 Hz"
expect "$WORK/identify.txt" '^held out: .*10mm1Hz0A\.txt record 0: force NMSE [0-9.]+ %' "held-out test 10 mm 1 Hz"
expect "$WORK/identify.txt" '^dynamic stiffness K\*' "the dynamic stiffness table"
expect "$WORK/diagnose.txt" '^verdict: explained by coulomb_friction' "the diagnosis' verdict"
expect "$WORK/diagnose.txt" '^held-out record 0 \(sine\): force NMSE .* with linear -> .* with coulomb_friction' "held-out record 0 before and after"
expect "$WORK/diagnose.txt" '^held-out record 1 \(sine\): force NMSE .* with linear -> .* with coulomb_friction' "held-out record 1 before and after"
echo "real_damper: all checks passed"
