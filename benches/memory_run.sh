#!/usr/bin/env bash
# Flat memory over a long 10 kHz rig run: the simulated sensor publishes a run
# of STEPS 13 s sine steps (1.6-3.4 Hz, cycled) and the two band-random records, simulated while
# published, as fast as the recorder acknowledges; the recorder writes it to a bag; the sensor
# plays the bag back into a second recorder; `forcemap identify` reads it offline. The RSS of
# every process is sampled each second; printed: first sample (after 2 s) -> peak -> last.
# Usage: bash benches/memory_run.sh STEPS [OUT_DIR]   (an hour at 10 kHz: STEPS = 275)
# FORCEMAP names the forcemap binary (release build); OUT_DIR defaults to a new /tmp dir and
# should have room for about 110 bytes per sample.
set -euo pipefail
steps="${1:?STEPS}"
out="${2:-$(mktemp -d /tmp/forcemap-memory-XXXX)}"
fm="${FORCEMAP:?FORCEMAP: the forcemap binary}"
mkdir -p "$out"
freqs=$(python3 -c "print('[' + ','.join(f'{1.6 + 0.2 * (i % 10):.1f}' for i in range($steps)) + ']')")
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( (RANDOM % 100) + 100 ))}"

# rss_log PID NAME: VmRSS (kB) each second while PID lives, into $out/NAME.rss.
rss_log() {
  local pid=$1 name=$2
  while kill -0 "$pid" 2>/dev/null; do
    awk '/VmRSS/ {print $2}' "/proc/$pid/status" 2>/dev/null >> "$out/$name.rss" || true
    sleep 1
  done
}
summary() {
  local f="$out/$1.rss"
  awk -v n="$1" 'NR == 3 {e = $1} {if ($1 > p) p = $1; l = $1}
    END {printf "%-16s %d samples of RSS: early %.1f MiB, peak %.1f MiB, last %.1f MiB\n", n, NR, e / 1024, p / 1024, l / 1024}' "$f"
}

run_pair() { # NAME_SUFFIX SENSOR_ARGS...: a recorder and a sensor; waits for the sensor.
  local tag=$1; shift
  "$fm" node recorder --ros-args -r __ns:=/rig -p bag:="$out/bag_$tag" -p overwrite:=true \
    -p "topics:=[samples,excitation,parameters]" > "$out/recorder_$tag.log" 2>&1 &
  local rec=$!
  rss_log $rec "recorder_$tag" &
  "$fm" node sensor --ros-args -r __ns:=/rig -p rate_factor:=0.0 -p linger_s:=1.0 "$@" \
    > "$out/sensor_$tag.log" 2>&1 &
  local sen=$!
  rss_log $sen "sensor_$tag" &
  local t0=$SECONDS
  wait $sen
  echo "sensor ($tag) done in $((SECONDS - t0)) s: $(tail -n 2 "$out/sensor_$tag.log" | head -n 1)"
  sleep 2
  kill -INT $rec
  wait $rec || true
  sleep 1.2
}

run_pair sim -p sample_rate_hz:=10000.0 -p "frequencies_hz:=$freqs"
run_pair play -p source:=bag -p bag:="$out/bag_sim"
du -sh "$out/bag_sim"
"$fm" identify "$out/bag_sim" --model coulomb --json > "$out/identify.json" &
id=$!
rss_log $id identify &
t0=$SECONDS
wait $id
echo "identify done in $((SECONDS - t0)) s"
sleep 1.2
for n in sensor_sim recorder_sim sensor_play recorder_play identify; do summary $n; done
echo "logs and RSS traces in $out"
