#!/bin/bash
# User-shaped files through `import`, `estimate` and `estimate --follow`
# (docs/import.md, "Checked on user-shaped files"): gen.py writes them
# (seed 1: 18 formats x 6 rigs, realistic variants and malformed files;
# seed 2: the well-formed ones again, other rigs), run.py runs the binary
# on each (60 s and 6 GiB a command), analyze.py sums up. From the
# repository root, after `cargo build --release -p trainer`; about 8 min.
set -e
D=runs/import-check
mkdir -p $D
H=docs/import-check
FUZZ_ROOT=$D/files FUZZ_MANIFEST=$D/manifest.json python3 $H/gen.py 1
FUZZ_ROOT=$D/files2 FUZZ_MANIFEST=$D/manifest2.json FUZZ_GOOD_ONLY=1 python3 $H/gen.py 2
export FUZZ_DIR=$(pwd)/$D
FUZZ_MANIFEST=$D/manifest.json FUZZ_RESULTS=$D/results.jsonl python3 $H/run.py > $D/run.log
FUZZ_MANIFEST=$D/manifest2.json FUZZ_RESULTS=$D/results2.jsonl python3 $H/run.py > $D/run2.log
{ echo '# seed 1'; python3 $H/analyze.py $D/results.jsonl; echo; echo '# seed 2, well-formed only'; python3 $H/analyze.py $D/results2.jsonl; } > $H/results.txt
