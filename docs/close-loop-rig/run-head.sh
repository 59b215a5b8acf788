#!/bin/bash
# The loop ending in a rig blob, rerun at b201dea on q2, the encoder swings
# and the lab recordings whose import changed since their rows were
# measured (0a4203e: uneven stamps, including the 12 and 30 Hz ones that
# six decimals make uneven, differentiated over the grid's samples), and
# the friction-stopped ones measured before c5c8ba8 (a release ends where
# its swing sinks into the noise). Each
# run's report under runs/cl-rig-*, then the summary
# (results-b201dea.md). From the repository root, after
# `cargo build --release -p trainer`.

. docs/close-loop-rig/common.sh
for s in 61 67 83 89 97; do $K generate --lab $s --offset 0.03 --seconds 40,90 --out runs/lab$s; done
run q2 $S/video-tracked/q2_data.csv --time-column 1 --angle-column 2
run encoder --rig rod $E/pendulum_free_swing_data_01.txt $E/pendulum_free_swing_data_02.txt $E/pendulum_free_swing_data_03.txt
for r in 67-2-coulomb 67-4-viscous-drag 83-7-coulomb-offset 67-1-viscous 97-5-viscous-coulomb 61-7-coulomb-offset 83-3-drag 61-2-coulomb 61-5-viscous-coulomb \
         83-2-coulomb 89-2-coulomb 67-7-coulomb-offset 89-7-coulomb-offset; do
  run lab$r runs/lab${r%%-*}/lab-$r.csv
done
{ echo '# close-loop at b201dea: the recordings whose import changed'; echo
  for s in 61 67 83 89 97; do python3 docs/close-loop-rig/collect.py $s; echo; done
} > docs/close-loop-rig/results-b201dea.md
