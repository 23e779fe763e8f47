#!/usr/bin/env bash
# A real friction damper with backlash (data/real/friction_damper_arts: one JSON file per test,
# inches and kips, as the lab published them): ramped sine tests and an earthquake history, each
# file one record with no steps. The damper model fitted to three tests sample by sample and
# checked on two held-out tests and the earthquake history, then the gap diagnosis of a linear
# model, which names the friction's hysteresis loop.
#
#   bash examples/friction_damper.sh [SCRATCH_DIR]   # FORCEMAP=path/to/forcemap to choose the binary
#
# Exits non-zero when an expected line of the output is missing.
set -euo pipefail

source "$(dirname "$0")/lib.bash"
# The data are read where they lie in the repository; what the example writes goes to $WORK.
cd "$REPO"

D=data/real/friction_damper_arts
FIT=("$D/1Hz30lbtension0.5amplitude.json" "$D/1Hz30lbtension1.5amplitude.json" "$D/2Hz30lbtension0.5amplitude.json")
HELD=(--validate "$D/1Hz30lbtension1amplitude.json" --validate "$D/0.5Hz30lbtension1amplitude.json"
    --validate "$D/ImperialValleyDBE.json")

say "1. The channel map: the JSON matrix 'data', its columns by position, inches and kips"
cat "$D/map.yaml"

say "2. What forcemap finds in the six files (each one record: the sines ramp, the earthquake is no sine)"
run info "$D"/*.json --channels "$D/map.yaml" | grep -v '^notice' | tee "$WORK/info.txt"

say "3. The damper model fitted to three tests on their samples, predicting the three held out"
run identify "${FIT[@]}" --channels "$D/map.yaml" --model damper "${HELD[@]}" \
    | grep -v '^notice' | tee "$WORK/identify.txt"

say "4. What a linear model misses, and which effect closes the gap (the same tests)"
run diagnose "${FIT[@]}" --channels "$D/map.yaml" --model linear "${HELD[@]}" \
    | grep -v '^notice' | tee "$WORK/diagnose.txt"

say "Checks"
expect "$WORK/identify.txt" 'model damper by output-error' "identified on the records' samples"
expect "$WORK/identify.txt" '^held out: .*ImperialValleyDBE\.json record 0: force NMSE [0-9.]+ %' "the earthquake history held out"
expect "$WORK/diagnose.txt" 'on 3 records with no steps' "the diagnosis fits the records' samples"
expect "$WORK/diagnose.txt" '^verdict: explained by hysteresis' "the diagnosis' verdict"
expect "$WORK/diagnose.txt" '^held-out record 2 \(unlabelled\): force NMSE .* with linear -> .* with hysteresis' "the earthquake history before and after"
echo "friction_damper: all checks passed"
