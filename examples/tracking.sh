#!/usr/bin/env bash
# Tracking drifting parameters offline: a damper that heats up on the dyno and loses damping
# step by step, identified with a forgetting factor (`--forgetting-per-step 0.8`, a window of
# about four steps), which prints theta after every step; the tracked damping c follows the
# fade where the converged estimate would give the run's average.
# The run is forcemap's simulated dyno (`forcemap simulate --system damper-dyno`, 40 dB, twelve
# sine steps of 4 s) with the fade added to its force here: c falls by 2.5 % of its 1750 N s/m
# at each step, 30 % over the run.
#
#   bash examples/tracking.sh [SCRATCH_DIR]          # FORCEMAP=path/to/forcemap to choose the binary
#
# Exits non-zero when the tracked table is missing or its last c is off the truth by more than 5 %.
set -euo pipefail

source "$(dirname "$0")/lib.bash"
cd "$WORK"

C0=1750    # the simulated damper's damping [N s/m]
FADE=0.025 # the share of C0 lost per step

say "1. The dyno run, noise-free (for the velocity) and at 40 dB SNR (the measurement)"
run simulate --system damper-dyno --csv clean.csv
run simulate --system damper-dyno --snr-db 40 --csv measured.csv

say "2. The damper heats up: its force loses FADE * C0 * step * velocity"
# Columns: time_s, step, frequency_hz, relative_displacement_m, mass_acceleration_mps2, force_n.
# The velocity is the central difference of the noise-free displacement within each step; the
# fade is added to the measured force, so the noise stays the measurement's.
awk -F, -v OFS=, -v c0="$C0" -v fade="$FADE" '
    NR == FNR { t[FNR] = $1; s[FNR] = $2; x[FNR] = $4; n = FNR; next }
    FNR == 1 { print; next }
    {
        lo = (FNR > 2 && s[FNR - 1] == s[FNR]) ? FNR - 1 : FNR
        hi = (FNR < n && s[FNR + 1] == s[FNR]) ? FNR + 1 : FNR
        v = (x[hi] - x[lo]) / (t[hi] - t[lo])
        $6 = sprintf("%.17g", $6 - fade * $2 * c0 * v)
        print
    }' clean.csv measured.csv > drifting.csv
head -n 3 drifting.csv

say "3. Identify with forgetting: theta after every step"
# The first row rests on one step at one frequency, where the spring and the fixture's mass
# cannot be told apart; the rows settle from the second step on. The fit against the noise warns
# that the model explains the run worse than its noise allows: one constant c cannot fit steps
# whose damping differs, which is what tracking is for.
run identify drifting.csv --model damper --forgetting-per-step 0.8 | tee identify.txt

say "4. The tracked c against the damper's c at each step"
awk -v c0="$C0" -v fade="$FADE" '
    /^tracked theta after each step/ { on = 1; next }
    on && $1 == "step" { for (i = 1; i <= NF; i++) if ($i == "[s]") base = i; for (i = 1; i <= NF; i++) if ($i == "c") col = i - base + 2; next }
    on && $1 == "0" { printf "step  0  (one step at one frequency: spring and fixture mass not yet told apart)\n"; next }
    on && $1 ~ /^[0-9]+$/ { truth = c0 * (1 - fade * $1); printf "step %2d  tracked c %9.1f  truth %7.1f  (%+.1f %%)\n", $1, $col, truth, ($col - truth) / truth * 100; last = $1; lastc = $col; lastt = truth; next }
    on { on = 0 }
    END { if (last == "") exit 1; err = (lastc - lastt) / lastt * 100; if (err < 0) err = -err
          printf "%s the last tracked c is %.1f %% off the truth (limit 5 %%)\n", (err <= 5) ? "ok:" : "FAILED:", err; exit !(err <= 5) }
' identify.txt | tee track.txt

say "Checks"
expect identify.txt '^tracked theta after each step' "the tracked-theta table"
expect identify.txt '^ +11 +48\.000 ' "its row after the last step"
expect track.txt '^ok: the last tracked c' "the tracked c follows the fade"
echo "tracking: all checks passed"
