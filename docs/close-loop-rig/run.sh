#!/bin/bash
# The loop ending in a rig blob, on the shared real recordings and on lab-like
# recordings of seed 61 (never tuned on): each run's report under runs/cl-rig-*,
# then the summary table (collect.py). From the repository root, after
# `cargo build --release -p trainer`.

. docs/close-loop-rig/common.sh
run q2 $S/video-tracked/q2_data.csv --time-column 1 --angle-column 2
run encoder --rig rod $E/pendulum_free_swing_data_01.txt $E/pendulum_free_swing_data_02.txt $E/pendulum_free_swing_data_03.txt
$K generate --lab 61 --offset 0.03 --seconds 40,90 --out runs/lab61
for c in 1-viscous 2-coulomb 3-drag 4-viscous-drag 5-viscous-coulomb 7-coulomb-offset; do
  run lab61-$c runs/lab61/lab-61-$c.csv
done
python3 docs/close-loop-rig/collect.py > docs/close-loop-rig/results.md
