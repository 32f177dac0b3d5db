# The engine's plumbing before (9bb0718) and after (HEAD), full length (the certificate off, so
# the near-zero rule does not change the work), alternated, warm compile cache.
set -e
. /work/main/.venv/bin/activate
cd /tmp
G="--forces 0:150:10 --durations 0.1,0.2,0.3,0.5 --set scenario.t_end=4 --physics mjx -q"
for v in base9 snap; do PYTHONPATH=/tmp/$v/src python -m mjx_balance sweep $G --full-length --out /tmp/ab/warm_$v >/dev/null 2>&1; done
for i in 1 2 3; do
  for v in base9 snap; do
    rm -rf /tmp/ab/$v
    t0=$(date +%s.%N)
    PYTHONPATH=/tmp/$v/src python -m mjx_balance sweep $G --full-length --out /tmp/ab/$v >/dev/null 2>&1
    t1=$(date +%s.%N)
    echo "$v full-length run $i: $(echo "$t1 - $t0" | bc) s"
  done
done
