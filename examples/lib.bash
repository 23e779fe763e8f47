# What every example shares, sourced by each script (not run alone): the binary to run, the
# scratch directory, and the helpers that print a command with its output and check it.
#
#   source "$(dirname "$0")/lib.bash"   # sets FORCEMAP (absolute), REPO and WORK (absolute, made)
#
# FORCEMAP is the binary (default: `forcemap` on the PATH); the script's first argument is the
# scratch directory (default: a new `mktemp -d` directory).

FORCEMAP="${FORCEMAP:-forcemap}"
case "$FORCEMAP" in */*) FORCEMAP="$(cd "$(dirname "$FORCEMAP")" && pwd)/$(basename "$FORCEMAP")" ;; esac
command -v "$FORCEMAP" >/dev/null || { echo "no forcemap binary: put it on PATH or set FORCEMAP" >&2; exit 2; }
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
WORK="${1:-$(mktemp -d)}"
mkdir -p "$WORK" && WORK="$(cd "$WORK" && pwd)"
echo "scratch directory: $WORK"

say() { printf '\n== %s\n' "$*"; }
run() { printf '$ forcemap %s\n' "$*"; "$FORCEMAP" "$@" 2>&1; }
# expect FILE REGEX WHAT: the line must be in the output, or the example fails.
expect() {
    if grep -Eq -- "$2" "$1"; then echo "ok: $3"; else echo "FAILED: $3 (no line matching '$2' in $1)" >&2; exit 1; fi
}
# near FILE NAME TRUTH PERCENT: the parameter's row 'NAME value std r' lies within PERCENT of TRUTH.
near() {
    awk -v name="$2" -v truth="$3" -v tol="$4" '
        $1 == name && NF == 4 { found = 1; err = ($2 - truth) / truth * 100
            printf "%s %-6s = %.4f (truth %g, %+.2f %%)\n", (err <= tol && err >= -tol) ? "ok:" : "FAILED:", name, $2, truth, err
            exit !(err <= tol && err >= -tol) }
        END { if (!found) { print "FAILED: no row for " name; exit 1 } }' "$1"
}
