#!/usr/bin/env bash
# The control cycle at 1 kHz through the real EtherCAT master (the sensor
# driver's ethercrab backend) and KickCAT's emulated CiA 402 drive, beside
# the same processes on the simulator's bus, one after the other in one run:
# the driver's round trip (sample published -> the controller's command
# received, `--round-trip-report`) p50/p99/p99.9/max, and the EtherCAT
# counters. BENCHMARKS.md, "EtherCAT".
#
# Usage: tools/scripts/bench_ethercat.sh [SECONDS=20]   (from the workspace root)
#   WARMUP=s   round trips left out at the start (default 0.5)
#   RATE=Hz    the cycle (default 1000; an integer)
#   SPIN_US=us the last part of each wait for the cycle spent polling the
#              clock (`bus.ethercat.wake_spin_us`; default 0: asleep to the
#              deadline)
#   FULL=1     the rows run the paper's whole protocol (experiments 1-9,
#              periods 1-10, about 33 min) instead of the run files' short
#              ones, so that a long row (600 s) ends by the bench's stop,
#              not by the protocol's end (after which the controller exits
#              and the driver latches `CommandDeadlineMissed`)
#   SKIP_KICKCAT=1  leave out the first row (KickCAT's own still motor):
#              the two rows that run the protocol, for long rows
#   CAPTURE=file.pcap  capture the master's interface during the first row
#              with tcpdump (not installed by this script), for
#              tools/scripts/ethercat_capture.py
# Needs: unshare -n as root (else unshare -rn: a user namespace, where the
# processes' own SCHED_FIFO and mlock requests are refused), ip, chrt -f.
# Three rows: `ethercat-kickcat`, KickCAT's own motor with torque scale 0 (a
# drive that holds still: a free KickCAT motor under the protocol's torques
# runs away past the controller's angle limits within a second);
# `ethercat-exo-plant`, the drive whose mechanics are our plant
# (tools/plant-drive, configs/ethercat-exo.toml: the same plant, subject and
# protocol as the simulator row); `simulator-bus`, that run file on the
# simulator's bus with exo-plant-sim. A late cycle or frame latches the
# driver's safe state by design, and a latched driver records no round
# trips: an EtherCAT row's `n` counts those before its latch.
set -euo pipefail
secs=${1:-20}
root=$(pwd)
target=${CARGO_TARGET_DIR:-$root/target}
profile=${PROFILE:-release}
flag=--release; [ "$profile" = dev ] && flag=
cargo build $flag -p exo-sensor-driver -p exo-controller -p exo-plant-sim -p exo-plant-drive >/dev/null
bin=$target/$([ "$profile" = dev ] && echo debug || echo release)
kc=$target/kickcat
../shared/vendor/kickcat/build.sh "$kc" >/dev/null
pd=$target/plant-drive
tools/plant-drive/build.sh "$pd" "$bin/libexo_plant_drive.a" >/dev/null
warmup=${WARMUP:-0.5}
rate=${RATE:-1000}
# A still motor: our slave config beside the vendored one (same ESI).
cat > "$kc/slave_configs/ecat402-drive-still.json" <<'JSON'
{ "esi": "ecat402-drive.xml", "ds402_motor": true, "motor_torque_scale": 0.0 }
JSON
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
# A shipped run file with its paths absolute, at $rate Hz: the deadlines
# kept in periods as the files give them at 1 kHz (command 1, bus 5, the
# drive's watchdog 10; the controller's sample deadline stays 50 ms).
full=()
[ "${FULL:-0}" = 1 ] && full=(-e 's|^experiments = \[.*\]|experiments = [1, 2, 3, 4, 5, 6, 7, 8, 9]|'
                            -e 's|^periods = \[.*\]|periods = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]|')
absolute() {
  local ms; ms=$(awk "BEGIN { print 1000 / $rate }")
  sed -e "s|plant_model = \"|plant_model = \"$root/configs/|" \
      -e "s|subject_file = \"|subject_file = \"$root/configs/|" \
      -e "s|experiments_file = \"|experiments_file = \"$root/configs/|" \
      -e "s|output_dir = \"out/runs\"|output_dir = \"$out/runs\"|" \
      -e "s|^rate_hz = 1000.0|rate_hz = $rate.0|" \
      -e "s|^command_deadline_ms = 1.0|command_deadline_ms = $ms|" \
      -e "s|^bus_deadline_ms = 5.0|bus_deadline_ms = $(awk "BEGIN { print 5 * $ms }")|" \
      -e "s|^drive_watchdog_ms = 10.0|drive_watchdog_ms = $(awk "BEGIN { print 10 * $ms }")|" \
      -e "s|^\[bus.ethercat\]\$|[bus.ethercat]\nwake_spin_us = ${SPIN_US:-0}.0|" \
      "${full[@]}" \
      "configs/$1"
}
absolute ethercat-kickcat.toml > "$out/ecat.toml"
cat >> "$out/ecat.toml" <<'TOML'

[realtime]
plant_sim_cpu = 1
sensor_driver_cpu = 1
controller_cpu = 1
sched_fifo_priority = 80
lock_memory = true
TOML
absolute ethercat-exo.toml > "$out/plant.toml"
sed -e 's|backend = "ethercat"|backend = "simulator"|' -e 's|plant_sim = false|plant_sim = true|' \
    -e 's|instance = "exoplantecat"|instance = "exoplantsim"|' -e 's|^sensor_driver_cpu = 1|plant_sim_cpu = 1\nsensor_driver_cpu = 1|' \
    "$out/plant.toml" > "$out/sim.toml"
fifo=; chrt -f 40 true 2>/dev/null && fifo="chrt -f 40"
# As root a network namespace alone: the processes' SCHED_FIFO 80 and
# mlockall are then granted (inside a user namespace they are refused).
ns="unshare -rn"; [ "$(id -u)" = 0 ] && ns="unshare -n"

run() { # run NAME CONFIG WITH_PLANT
  local name=$1 cfg=$2 plant=$3 pids=()
  [ "$plant" = 1 ] && { "$bin/exo-plant-sim" --config "$cfg" 2>"$out/$name-plant.log" & pids+=($!); }
  "$bin/exo-controller" --config "$cfg" 2>"$out/$name-controller.log" & pids+=($!)
  sleep 2 # the controller's ports up before the cycle starts (iceoryx2 builds a connection on first use)
  "$bin/exo-sensor-driver" --config "$cfg" --round-trip-report "$out/$name.json" --round-trip-warmup-s "$warmup" 2>"$out/$name-driver.log" & local drv=$!
  sleep "$secs"
  kill -TERM "$drv" "${pids[@]}" 2>/dev/null || true
  wait "$drv" || true; wait "${pids[@]}" 2>/dev/null || true
  printf '%-22s ' "$name"
  python3 - "$out/$name.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
if not r: print("no round trip recorded"); sys.exit()
l = r; us = lambda k: l[k] / 1000
print(f"n={l['count']:6d}  p50 {us('p50_ns'):7.1f} us  p99 {us('p99_ns'):7.1f} us  p99.9 {us('p999_ns'):7.1f} us  max {us('max_ns'):8.1f} us")
PY
  grep -h "real-time settings\|driver's part\|not permitted\|safe state latched\|EtherCAT fault\|EtherCAT exchange\|EtherCAT wake-up\|EtherCAT [0-9]* cycles" "$out/$name-driver.log" | head -10 | sed 's/^ *[A-Z]* sensor-driver: /    /' || true
}

export -f run 2>/dev/null || true
echo "machine: $(nproc) CPUs, $(uname -r), load $(cut -d' ' -f1-3 /proc/loadavg); $secs s per row, $rate Hz, $profile build, warm-up $warmup s, wake-up spin ${SPIN_US:-0} µs"
echo "namespace: $ns; scheduling of the namespace: ${fifo:-normal}"
$fifo $ns bash -c "
  set -e
  for c in 'ecm0 type veth peer name ecm0b' 'ecs0 type veth peer name ecs0b' 'br0 type bridge'; do ip link add \$c; done
  ip link set ecm0b master br0; ip link set ecs0b master br0
  for l in lo br0 ecm0b ecs0b ecm0 ecs0; do ip link set \$l up; done
  cd '$kc'; ./network_simulator -i ecs0 -s slave_configs/ecat402-drive-still.json >/dev/null 2>&1 & sim=\$!
  sleep 1; cd '$root'
  $(declare -f run); out='$out' bin='$bin' secs='$secs' warmup='$warmup'
  cap='${CAPTURE:-}'; td=
  if [ -n \"\$cap\" ]; then tcpdump -i ecm0 -j adapter_unsynced --time-stamp-precision=nano -w \"\$cap\" 2>/dev/null & td=\$!; sleep 1; fi
  [ '${SKIP_KICKCAT:-0}' = 1 ] || run ethercat-kickcat '$out/ecat.toml' 0
  if [ -n \"\$td\" ]; then kill \$td; sleep 0.5; fi
  kill \$sim; sleep 0.5
  '$pd/exo_plant_drive' -i ecs0 -s '$pd/slave_configs/exo-drive.json' -r '$out/plant.toml' >/dev/null 2>'$out/drive.log' & sim=\$!
  sleep 1
  run ethercat-exo-plant '$out/plant.toml' 0
  kill \$sim
  run simulator-bus '$out/sim.toml' 1
"
