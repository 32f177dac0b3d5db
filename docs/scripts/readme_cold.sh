#!/usr/bin/env bash
# The README's test command, cold: a fresh clone of this checkout's HEAD (no compilation cache,
# no virtual environment), the command exactly as the README gives it, and its wall time.
# Run from the repository root on a quiet machine (the tests measure themselves with the
# machine's cores): bash docs/scripts/readme_cold.sh [FOLDER]   (default: a new temporary one)
set -uo pipefail
repo="$(cd "$(dirname "$0")/../.." && pwd)"
dir="${1:-$(mktemp -d)/clone}"
rm -rf "$dir" && git clone -q "$repo" "$dir" && cd "$dir" || exit 1
log="$dir.log"
start=$(date +%s.%N)
bash -c 'python3 -m venv .venv && . .venv/bin/activate && pip install -e ".[test]" && pytest -q' \
    > "$log" 2>&1
rc=$?
end=$(date +%s.%N)
tail -n 1 "$log"
echo "exit $rc, the whole command $(echo "$end - $start" | bc) s (log: $log)"
