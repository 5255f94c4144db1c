#!/bin/bash
# Runs the round trip whenever the machine is idle (>= 80 % over two seconds), for up to 90
# minutes: the two-process ping-pong (blocking reads, epoll, epoll after a 20 µs spin) and
# `armor-bench latency_64b` of two builds. Usage: idle_watch.sh PINGPONG BENCH_DIR_A BENCH_DIR_B
PINGPONG=$1; A=$2; B=$3
idle() {
  read -r _ u n s i w x y z _ < /proc/stat; t1=$((u+n+s+i+w+x+y+z)); i1=$i; sleep 2
  read -r _ u n s i w x y z _ < /proc/stat; t2=$((u+n+s+i+w+x+y+z))
  echo $(( 100*(i-i1)/(t2-t1) ))
}
end=$(( $(date +%s) + 5400 ))
while [ "$(date +%s)" -lt $end ]; do
  p=$(idle)
  if [ "$p" -ge 80 ]; then
    echo "=== $(date +%T) idle=$p% $(uptime)"
    for m in block "epoll 0" "epoll 20"; do $PINGPONG $m 2>/dev/null; done
    echo -n "A: "; "$A"/armor-bench latency_64b 2>/dev/null | grep bench
    echo -n "B: "; "$B"/armor-bench latency_64b 2>/dev/null | grep bench
    echo "after: idle=$(idle)%"
  fi
done
