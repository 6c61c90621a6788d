#!/bin/bash
# sidestep tick-time series, default scheduling and --realtime-priority 49 alternated
cd /work/main
N=${1:-8}
for r in $(seq 1 $N); do
  ./target/release/legwork bench mpc --tasks sidestep --push 0 --horizons 0.5 --thread-counts 2 --json --out /tmp/s52/tick/default-$r > /tmp/s52/tick/default-$r.log 2>&1
  ./target/release/legwork bench mpc --tasks sidestep --push 0 --horizons 0.5 --thread-counts 2 --realtime-priority 49 --json --out /tmp/s52/tick/fifo-$r > /tmp/s52/tick/fifo-$r.log 2>&1
done
echo done > /tmp/s52/tick/done
