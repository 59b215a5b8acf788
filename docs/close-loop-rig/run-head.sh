#!/bin/bash
# The loop ending in a rig blob, rerun at ce377c8 on the lab recordings
# whose import it changed by over 0.1% of the rate's rms (uneven stamps'
# end windows hold the grid's samples: the 12 and 30 Hz even files,
# written to six decimals, and the jittered ones), then q2, seed 89's
# viscous + Coulomb (measured before c5c8ba8), the encoder swings and
# seed 73's tail (12 Hz, dropped frames and tracker spikes). Each
# run's report under runs/cl-rig-*, then the summary (results-ce377c8.md).
# From the repository root, after `cargo build --release -p trainer`.

. docs/close-loop-rig/common.sh
for s in 61 67 83 89 97; do $K generate --lab $s --offset 0.03 --seconds 40,90 --out runs/lab$s; done
$K generate --lab 73 --offset 0.03 --seconds 60,120 --dropped 0.02 --spikes 0.005 --out runs/lab73
for r in 67-2-coulomb 67-4-viscous-drag 61-2-coulomb 61-5-viscous-coulomb 83-3-drag 97-5-viscous-coulomb 83-7-coulomb-offset; do
  run lab$r runs/lab${r%%-*}/lab-$r.csv
done
run q2 $S/video-tracked/q2_data.csv --time-column 1 --angle-column 2
run lab89-5-viscous-coulomb runs/lab89/lab-89-5-viscous-coulomb.csv
run encoder --rig rod $E/pendulum_free_swing_data_01.txt $E/pendulum_free_swing_data_02.txt $E/pendulum_free_swing_data_03.txt
run lab73-4-viscous-drag runs/lab73/lab-73-4-viscous-drag.csv
{ echo '# close-loop at ce377c8: the recordings whose import changed'; echo
  for s in 61 67 73 83 89 97; do python3 docs/close-loop-rig/collect.py $s; echo; done
} > docs/close-loop-rig/results-ce377c8.md
