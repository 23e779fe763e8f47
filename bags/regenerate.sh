#!/usr/bin/env bash
# Regenerates the committed sample bags from the simulators (seeded, so the messages are
# identical every time). Usage: bash bags/regenerate.sh [OUT_DIR]   (default: bags/)
# FORCEMAP may name the forcemap binary; otherwise it is built with cargo.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
out="${1:-$here}"
if [ -z "${FORCEMAP:-}" ]; then
  cargo build --release --quiet -p forcemap_cli --bin forcemap --manifest-path "$here/../Cargo.toml"
  FORCEMAP="$here/../target/release/forcemap"
fi
mkdir -p "$out"
rm -rf "$out/rig_40db" "$out/three_dof_case_i" "$out/three_dof_case_ii" "$out/damper_dyno_40db" \
  "$out/shaker_multisine_30db"
# The suspension-rig stand-in: 10 stepped-sine steps (identification) then two band-random
# records (validation), 40 dB SNR.
"$FORCEMAP" simulate --system rig --snr-db 40 --seed 1 --bag "$out/rig_40db"
# The 3-DOF example, noise-free, as in the paper's Table 1.
"$FORCEMAP" simulate --system three-dof --case i --bag "$out/three_dof_case_i"
"$FORCEMAP" simulate --system three-dof --case ii --bag "$out/three_dof_case_ii"
# An element test: a twin-tube damper on a displacement-driven dyno (preload, gas spring,
# rebound/compression damping, seal friction; 0.8 kg fixture), 4 frequencies x 3 strokes, 40 dB.
"$FORCEMAP" simulate --system damper-dyno --snr-db 40 --seed 1 --bag "$out/damper_dyno_40db"
# A force-driven single-DOF system with cubic stiffness (2 kg moving mass, identified): two
# random-odd multisine realisations (0.5 Hz lines over 4-25 Hz, 60 N RMS, 9 periods at 2 kHz)
# then a band-random validation record, 30 dB SNR. Its ExcitationState kind is MULTISINE.
"$FORCEMAP" simulate --system shaker-sdof --excitation multisine --snr-db 30 --seed 1 \
  --bag "$out/shaker_multisine_30db"
