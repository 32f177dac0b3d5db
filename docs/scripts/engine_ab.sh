#!/usr/bin/env bash
# The same sweep with two versions of the package, alternated, three times each (warm
# persistent compile cache after a first run of each): wall time of the whole command.
#     bash docs/scripts/engine_ab.sh BEFORE_CHECKOUT AFTER_CHECKOUT [extra sweep options]
# Full length by default, so that a certificate change does not change the work.
set -euo pipefail
before=$(realpath "$1"); after=$(realpath "$2"); shift 2
work=$(mktemp -d)
G=(--forces 0:150:10 --durations 0.1,0.2,0.3,0.5 --set scenario.t_end=4 --physics mjx -q
   --full-length "$@")
for v in "$before" "$after"; do
    PYTHONPATH="$v/src" python -m mjx_balance sweep "${G[@]}" --out "$work/warm" >/dev/null 2>&1
    rm -rf "$work/warm"
done
for i in 1 2 3; do
    for v in "$before" "$after"; do
        t0=$(date +%s.%N)
        PYTHONPATH="$v/src" python -m mjx_balance sweep "${G[@]}" --out "$work/run" >/dev/null 2>&1
        t1=$(date +%s.%N)
        rm -rf "$work/run"
        echo "$v run $i: $(echo "$t1 - $t0" | bc) s"
    done
done
rm -rf "$work"
