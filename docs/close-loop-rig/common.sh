# Sourced by run.sh and run-head.sh: the binary, the shared recordings, and
# one close-loop run (a name, then close-loop's arguments), its report in
# runs/cl-rig-NAME.md and its wall time in runs/cl-rig-NAME.time.
K=./target/release/koopman
S=../shared/data/measured
E=$S/rotary-encoder
run() {
  local name=$1; shift
  { time $K close-loop --weights weights/rig.kkf --quiet --out runs/cl-rig-$name "$@" > runs/cl-rig-$name.md ; } 2> runs/cl-rig-$name.time
}
