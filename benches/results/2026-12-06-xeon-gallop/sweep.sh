#!/bin/bash
# usage: sweep.sh NAME "SET ARGS" latencies...
name=$1; sets=$2; shift 2
for L in "$@"; do
  out=/tmp/s54/sw/$name-L$L
  ./target/release/legwork mpc gallop --sim mujoco --knot-dt 0.001 --horizon 0.2 --substeps 4 --feedback physical --tracking 10 --latency $L $sets --out $out > $out.log 2>&1
  plan=$(grep "base x at the end" $out.log | awk '{print $8, $9}')
  echo "$name L=$L: plan x $(grep 'base x at the end' $out.log | sed 's/  */ /g' | cut -d' ' -f10-) | low $(grep 'lowest base' $out.log | sed 's/  */ /g' | cut -d' ' -f6-) | $(tail -1 $out.log | cut -c1-14)"
done
