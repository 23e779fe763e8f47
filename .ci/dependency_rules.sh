#!/usr/bin/env bash
# The dependency rule of each crate (stated in its README), checked on its normal dependency
# tree (transitive, as cargo resolves it when the crate is built alone). Exits non-zero, naming
# the crate and the forbidden dependency, when a rule is broken.
set -euo pipefail
cd "$(dirname "$0")/.."

# crate | depth (all: the whole tree; 1: the crate's own dependencies) | forbidden crates | why
# The nodes' rule is on their own dependencies: ros2-client itself depends on clap.
rules=(
  "forcemap_math|all|tokio|ros2-client|rustdds|mcap|csv|serde_json|serde-saphyr|matfile|clap|plotters|indicatif|forcemap_eval|forcemap_msgs|forcemap_io|forcemap_nodes|forcemap_cli|the mathematics: no I/O, no async, no ROS"
  "forcemap_eval|all|tokio|ros2-client|rustdds|mcap|csv|serde_json|serde-saphyr|matfile|clap|plotters|indicatif|forcemap_msgs|forcemap_io|forcemap_nodes|forcemap_cli|the evaluation harnesses: as the mathematics (no I/O, no async, no ROS), on forcemap_math only"
  "forcemap_msgs|all|tokio|ros2-client|rustdds|mcap|clap|plotters|forcemap_eval|forcemap_io|forcemap_nodes|forcemap_cli|messages: no ROS runtime unless its feature ros2-client is asked for"
  "forcemap_io|all|tokio|ros2-client|rustdds|clap|plotters|indicatif|forcemap_eval|forcemap_nodes|forcemap_cli|file formats: no ROS runtime, no async, no command line"
  "forcemap_nodes|1|clap|plotters|indicatif|forcemap_eval|forcemap_cli|the nodes: no command-line parsing, no plotting"
)

failed=0
for rule in "${rules[@]}"; do
  IFS='|' read -r -a parts <<<"$rule"
  crate="${parts[0]}"
  depth="${parts[1]}"
  why="${parts[${#parts[@]}-1]}"
  forbidden=("${parts[@]:2:${#parts[@]}-3}")
  depth_arg=()
  [ "$depth" = all ] || depth_arg=(--depth "$depth")
  pattern="^($(IFS='|'; echo "${forbidden[*]}")) "
  tree="$(cargo tree -p "$crate" -e normal --prefix none "${depth_arg[@]}")"
  hits="$(grep -E "$pattern" <<<"$tree" | sort -u || true)"
  if [ -n "$hits" ]; then
    echo "dependency rule broken: $crate ($why) depends on:" >&2
    sed 's/^/  /' <<<"$hits" >&2
    failed=1
  else
    echo "$crate: ok ($why)"
  fi
done
exit "$failed"
