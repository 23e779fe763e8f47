#!/usr/bin/env bash
# Regenerates the figures of docs/figures/ with the commands the docs name beside them:
#
#   rig_force_state.svg          forcemap simulate --snr-db 40 --csv rig.csv
#                                forcemap identify rig.csv --model coulomb --mass-kg 36 --plot DIR
#                                (DIR/force_state.svg; docs/method.md)
#   mr_damper_utfsm_drive.svg    forcemap info data/real/mr_damper_utfsm/10mm1Hz0A.txt
#                                  --channels data/real/mr_damper_utfsm/map.yaml --plot DIR
#                                (DIR/drive_0.svg; docs/data.md)
#   diagnose_demo_heldout.svg    forcemap diagnose --demo --report DIR
#                                (DIR/heldout_10.svg; docs/diagnosis.md)
#
#   bash .ci/figures.sh [FORCEMAP]      # default target/release/forcemap
#
# The figures are committed; this script refreshes them after a change to the plots (it is not
# part of .ci/run). Every command is deterministic (seed 1, the committed data), so a second run
# rewrites the same bytes and leaves git with nothing to commit. Works in a scratch directory
# removed at the end; the commands that read the repository's data run from its root, so the
# file names in the plots' titles are the repository's.
set -euo pipefail
repo="$(cd "$(dirname "$0")/.." && pwd)"

# A path given is taken from where the script is called; the default from the repository's root.
FORCEMAP="${1:-$repo/target/release/forcemap}"
case "$FORCEMAP" in */*) FORCEMAP="$(cd "$(dirname "$FORCEMAP")" && pwd)/$(basename "$FORCEMAP")" ;; esac
cd "$repo"
command -v "$FORCEMAP" >/dev/null || {
    echo "no forcemap binary at $FORCEMAP: cargo build --release -p forcemap_cli --bin forcemap" >&2
    exit 2
}
out=docs/figures
mkdir -p "$out"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

# put SOURCE NAME: copies SOURCE to docs/figures/NAME and says whether it changed.
put() {
    test -s "$1" || { echo "figures: $1 was not written" >&2; exit 1; }
    if cmp -s "$1" "$out/$2"; then
        echo "figures: $out/$2 unchanged"
    else
        cp "$1" "$out/$2"
        echo "figures: $out/$2 written ($(wc -c < "$out/$2") bytes)"
    fi
}

echo "figures: the rig's force-state map"
(cd "$tmp" && "$FORCEMAP" simulate --snr-db 40 --csv rig.csv \
    && "$FORCEMAP" identify rig.csv --model coulomb --mass-kg 36 --plot rig_plots) > "$tmp/rig.log" 2>&1 \
    || { cat "$tmp/rig.log" >&2; exit 1; }
put "$tmp/rig_plots/force_state.svg" rig_force_state.svg

echo "figures: the real MR damper's 10 mm, 1 Hz test and the record found in it"
"$FORCEMAP" info data/real/mr_damper_utfsm/10mm1Hz0A.txt \
    --channels data/real/mr_damper_utfsm/map.yaml --plot "$tmp/mr_drive" > "$tmp/mr.log" 2>&1 \
    || { cat "$tmp/mr.log" >&2; exit 1; }
put "$tmp/mr_drive/drive_0.svg" mr_damper_utfsm_drive.svg

echo "figures: the diagnosis demo's held-out record, before and after"
"$FORCEMAP" diagnose --demo --report "$tmp/demo_report" > "$tmp/demo.log" 2>&1 \
    || { cat "$tmp/demo.log" >&2; exit 1; }
put "$tmp/demo_report/heldout_10.svg" diagnose_demo_heldout.svg
