#!/bin/bash
cd /work/main
F="computeMinverse|computeABADerivatives|computeRNEADerivatives"
for r in 1 2 3; do
  LEGWORK_ANCHORS_CACHE=/tmp/s52/noavx/cache /tmp/s52/noavx/run_pinocchio_bench_znver3.sh > /tmp/s52/noavx/pinocchio-$r.jsonl 2> /tmp/s52/noavx/pinocchio-$r.txt
  RUSTFLAGS="-C target-cpu=znver3" CARGO_TARGET_DIR=/work/tgt-znver3 cargo bench --bench dynamics -- "$F" > /tmp/s52/noavx/native-$r.txt 2>&1
  cargo bench --bench dynamics -- "$F" > /tmp/s52/noavx/portable-$r.txt 2>&1
done
LEGWORK_ANCHORS_CACHE=/tmp/s52/noavx/cache /tmp/s52/noavx/run_pinocchio_bench_znver3.sh > /tmp/s52/noavx/pinocchio-4.jsonl 2> /tmp/s52/noavx/pinocchio-4.txt
echo done > /tmp/s52/noavx/rounds-done
