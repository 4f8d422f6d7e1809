#!/usr/bin/env bash
# Online mode benchmark: the real VLP-16 capture (shared/data, looped) is
# replayed over loopback UDP at 1x and 5x its recorded rate into
# `forest-slam online`, which is then stopped with SIGINT. Prints the
# latency from capture (the driver delivering a revolution) to pose, light
# and dropped scans, and whether every revolution reached raw.rawlog.
# Both UDP receivers: ours (udp_receiver = forest-slam, the default) and
# MRPT's CVelodyneScanner loop (udp_receiver = mrpt). Ours stamps scans with
# the capture's GPS time; MRPT's with this PC's clock (its switch to GPS time
# when the first fix arrives would make time jump back to 2016).
# Traffic goes to 127.0.0.1 only (ports 42368/48308, or BENCH_PORT_BASE).
# Usage: scripts/bench-online.sh [BUILD_DIR] [LOOPS]
set -euo pipefail
BUILD=${1:-build}
LOOPS=${2:-20}
BIN="$BUILD/bin"
PCAP=../shared/data/mrpt/sample_velodyne_vlp16_gps.pcap
OUT="$BUILD/bench-online"
DATA_PORT=${BENCH_PORT_BASE:-42368}
POS_PORT=$((DATA_PORT + 1))
for b in forest-slam pcap-replay; do
  [ -x "$BIN/$b" ] || { echo "bench-online: $BIN/$b not built" >&2; exit 1; }
done
[ -f "$PCAP" ] || { echo "bench-online: $PCAP not found" >&2; exit 1; }
rm -rf "$OUT" && mkdir -p "$OUT"
for receiver in forest-slam mrpt; do
cat >"$OUT/live-$receiver.ini" <<INI
[VLP16]
driver = CVelodyneScanner
udp_receiver = $receiver
process_rate = 4000
sensorLabel = VLP16
model = VLP16
pos_packets_timing_timeout = $([ $receiver = mrpt ] && echo 0 || echo 30)
udp_data_port = $DATA_PORT
udp_position_port = $POS_PORT
[online]
status_period_s = 0
[pipeline]
lidar_label = VLP16_SCAN
gnss_label = VLP16_GPS
INI
done
echo "online benchmark: $PCAP x$LOOPS over 127.0.0.1 UDP, $(nproc) cores"
printf '%-12s %-5s %8s %9s %6s %8s %12s %9s %9s %16s %9s\n' receiver rate captured processed light dropped "latency med" p95 max "packets in/sent" "replay s"
for run in forest-slam:1 forest-slam:5 mrpt:1 mrpt:5; do
  receiver=${run%:*}
  rate=${run#*:}
  dir="$OUT/$receiver-rate$rate"
  log="$dir.log"
  "$BIN/forest-slam" online --config "$OUT/live-$receiver.ini" --out "$dir" >"$log" 2>&1 &
  pid=$!
  for _ in $(seq 300); do grep -qs "grabbing at" "$log" && break; sleep 0.1; done
  start=$(date +%s.%N)
  sent=$("$BIN/pcap-replay" --pcap "$PCAP" --rate "$rate" --loop "$LOOPS" --host 127.0.0.1 \
    --data-port "$DATA_PORT" --position-port "$POS_PORT" | sed -n 's/.*sent \([0-9]*\) data.*/\1/p')
  replay=$(echo "$(date +%s.%N) - $start" | bc -l)
  sleep 1
  kill -INT "$pid"
  wait "$pid" || { echo "bench-online: rate $rate failed, see $log" >&2; exit 1; }
  # "scans: 12 captured, 12 processed (10 mapped, 2 light), 0 dropped ..."
  line=$(grep '^scans:' "$log")
  cap=$(echo "$line" | sed -n 's/^scans: \([0-9]*\) captured.*/\1/p')
  proc=$(echo "$line" | sed -n 's/.* \([0-9]*\) processed.*/\1/p')
  light=$(echo "$line" | sed -n 's/.*, \([0-9]*\) light).*/\1/p')
  drop=$(echo "$line" | sed -n 's/.*light), \([0-9]*\) dropped.*/\1/p')
  lat=$(grep '^latency' "$log")
  med=$(echo "$lat" | sed -n 's/.*median \([0-9]*\) ms.*/\1/p')
  p95=$(echo "$lat" | sed -n 's/.*p95 \([0-9]*\) ms.*/\1/p')
  max=$(echo "$lat" | sed -n 's/.*max \([0-9]*\) ms.*/\1/p')
  packets=$(sed -n 's/^velodyne data packets in the scans: \([0-9]*\)/\1/p' "$log")
  printf '%-12s %-5s %8s %9s %6s %8s %9s ms %6s ms %6s ms %16s %9.1f\n' "$receiver" "${rate}x" "$cap" "$proc" "$light" "$drop" "$med" "$p95" "$max" "${packets:-0}/$sent" "$replay"
done
echo "(packets in: data packets in the delivered scans; the forest-slam receiver hands"
echo " over the revolution open at SIGINT, MRPT's keeps it: in < sent by up to ~76 there)"
