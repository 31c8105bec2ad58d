#!/bin/bash
# Check 3 A/B on this machine: c9b58bf (before issue 48) against main, interleaved, 2 rounds.
. /work/venv/bin/activate
out=/tmp/ab12f; mkdir -p $out
T=pt_naive,pt_inplace_regen,pt_compact_regen,bdpt_naive_connect,bdpt_parallel_connect,mlt
for round in 1 2 3; do
  for side in before main; do
    dir=/tmp/c9; [ $side = main ] && dir=/tmp/w12f
    date
    (cd $dir && PYTHONPATH=$dir python -m toolkit bench --repeats 1 --techniques $T > $out/cpu_${side}_$round.txt 2>&1)
    (cd $dir && PYTHONPATH=$dir python /work/main/results/issue48/ab_sizes.py $T > $out/gpu_${side}_$round.json 2>$out/gpu_${side}_$round.err)
  done
done
date
echo done > $out/DONE
