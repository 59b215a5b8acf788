#!/bin/bash
# The loop ending in a rig blob on inputs shaped unlike the lab sets of
# run.sh: a phone's rate-only gyroscope export (phone.py), the seven
# dissipative recordings of lab seed 73 with dropped frames (2%, in runs of
# up to 0.3 s) and tracker spikes (0.5%), and a 24 min recording at 1 kHz
# (seed 79's drag). Each run's report under runs/cl-rig-*, then the tables
# (collect.py). From the repository root, after
# `cargo build --release -p trainer`.

K=./target/release/koopman
run() { # name, then close-loop's arguments
  local name=$1; shift
  { time $K close-loop --weights weights/rig.kkf --quiet --out runs/cl-rig-$name "$@" > runs/cl-rig-$name.md ; } 2> runs/cl-rig-$name.time
}
python3 docs/close-loop-rig/phone.py runs/phone-gyro.csv
run phone runs/phone-gyro.csv
$K generate --lab 73 --offset 0.03 --seconds 60,120 --dropped 0.02 --spikes 0.005 --out runs/lab73
for c in 1-viscous 2-coulomb 3-drag 4-viscous-drag 5-viscous-coulomb 6-viscous-offset 7-coulomb-offset; do
  run lab73-$c runs/lab73/lab-73-$c.csv
done
$K generate --lab 79 --offset 0.03 --seconds 1200,1500 --out runs/lab79
run lab79-3-drag runs/lab79/lab-79-3-drag.csv
python3 docs/close-loop-rig/collect.py 73 > docs/close-loop-rig/results-73.md
python3 docs/close-loop-rig/collect.py 79 > docs/close-loop-rig/results-79.md
python3 docs/close-loop-rig/collect.py phone > docs/close-loop-rig/results-phone.md
