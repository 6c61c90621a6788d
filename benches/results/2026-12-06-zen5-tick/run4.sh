#!/bin/bash
cd /work/main
B="./target/release/legwork bench mpc --tasks sidestep --push 0 --horizons 0.5 --thread-counts 2 --json"
for r in $(seq 1 8); do
  $B --out /tmp/s52/tick/q-default-$r > /dev/null 2>&1
  $B --paced-timing --out /tmp/s52/tick/q-paced-$r > /dev/null 2>&1
  $B --realtime-priority 49 --out /tmp/s52/tick/q-fifo-$r > /dev/null 2>&1
  $B --realtime-priority 49 --paced-timing --out /tmp/s52/tick/q-fifopaced-$r > /dev/null 2>&1
done
echo done > /tmp/s52/tick/done4
