#!/bin/bash
while ! grep -q "ALL DONE" /tmp/final12.log; do sleep 10; done
. /work/venv/bin/activate
out=/tmp/ab12x; mkdir -p $out
date
for round in 1 2 3 4 5; do
  (cd /tmp/c9 && PYTHONPATH=/tmp/c9 python -m toolkit bench --repeats 1 --techniques mlt/pool,mlt > $out/mltpool_before_$round.txt 2>&1)
  (cd /tmp/w12f && PYTHONPATH=/tmp/w12f python -m toolkit bench --repeats 1 --techniques mlt,mlt/naive > $out/mltpool_main_$round.txt 2>&1)
done
date
for round in 1 2 3; do
  for side in before main; do
    dir=/tmp/c9; [ $side = main ] && dir=/tmp/w12f
    (cd $dir && PYTHONPATH=$dir python -m toolkit bench --repeats 5 --techniques pt_naive,mlt > $out/r5_${side}_$round.txt 2>&1)
  done
done
date
for round in 1 2 3 4 5 6 7; do
  for side in before main; do
    dir=/tmp/c9; [ $side = main ] && dir=/tmp/w12f
    (cd $dir && PYTHONPATH=$dir python /work/main/results/issue48/ab_sizes.py pt_naive > $out/gpu_ptnaive_${side}_$round.json 2>/dev/null)
  done
done
date
echo EXTRA DONE
