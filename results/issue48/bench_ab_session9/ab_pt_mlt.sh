#!/bin/bash
# The techniques below 1x in ab_repeats3.sh, again: bench --repeats 5, c9b58bf against main, interleaved, 3 rounds.
. /work/venv/bin/activate
out=/tmp/m9/ab_pt_mlt; mkdir -p $out
T=pt_inplace_regen,pt_compact_regen,mlt
for round in 1 2 3; do
  for side in before main; do
    dir=/tmp/c9; [ $side = main ] && dir=/work/main
    (cd $dir && PYTHONPATH=$dir python -m toolkit bench --repeats 5 --techniques $T > $out/cpu_${side}_$round.txt 2>&1)
  done
done
echo done > $out/DONE
