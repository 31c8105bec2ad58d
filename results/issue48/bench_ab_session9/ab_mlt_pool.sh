#!/bin/bash
# mlt like for like, A/B, 5 rounds at the CPU's sizes (bench --repeats 1): each start against the same start.
# c9b58bf's mlt/pool (its pool: 16 candidate iterations of the chains, the picked ones evaluated again) and
# mlt (start naive, its default) against main's mlt (start pool: the same 2,048 x 16 candidates, one batch)
# and mlt/naive.
. /work/venv/bin/activate
out=/tmp/m9/ab_mlt_pool; mkdir -p $out
for round in 1 2 3 4 5; do
  (cd /tmp/c9 && PYTHONPATH=/tmp/c9 python -m toolkit bench --repeats 1 --techniques mlt/pool,mlt > $out/cpu_before_$round.txt 2>&1)
  (cd /work/main && PYTHONPATH=/work/main python -m toolkit bench --repeats 1 --techniques mlt,mlt/naive > $out/cpu_main_$round.txt 2>&1)
done
echo done > $out/DONE
