#!/bin/bash
# mlt alone, A/B: c9b58bf's mlt (start naive, its default) against main's mlt (start pool) and mlt/naive, CPU's and GPU's sizes, 3 rounds.
. /work/venv/bin/activate
out=/tmp/m9/ab_mlt; mkdir -p $out
for round in 1 2 3 4; do
  (cd /tmp/c9 && PYTHONPATH=/tmp/c9 python -m toolkit bench --repeats 1 --techniques mlt > $out/cpu_before_$round.txt 2>&1)
  (cd /work/main && PYTHONPATH=/work/main python -m toolkit bench --repeats 1 --techniques mlt,mlt/naive > $out/cpu_main_$round.txt 2>&1)
  (cd /tmp/c9 && PYTHONPATH=/tmp/c9 python /work/main/results/issue48/ab_sizes.py mlt > $out/gpu_before_$round.json 2>/dev/null)
  (cd /work/main && PYTHONPATH=/work/main python /work/main/results/issue48/ab_sizes.py mlt,mlt/naive > $out/gpu_main_$round.json 2>/dev/null)
done
echo done > $out/DONE
