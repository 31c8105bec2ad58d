#!/bin/bash
# Check 3 at the CPU's sizes with less noise: bench --repeats 3 (each figure the median of three interleaved
# runs) of all six techniques, c9b58bf against main, interleaved, 2 rounds.
. /work/venv/bin/activate
out=/tmp/m9/ab_r3; mkdir -p $out
T=pt_naive,pt_inplace_regen,pt_compact_regen,bdpt_naive_connect,bdpt_parallel_connect,mlt
for round in 1 2; do
  for side in before main; do
    dir=/tmp/c9; [ $side = main ] && dir=/work/main
    (cd $dir && PYTHONPATH=$dir python -m toolkit bench --repeats 3 --techniques $T > $out/cpu_${side}_$round.txt 2>&1)
  done
done
echo done > $out/DONE
