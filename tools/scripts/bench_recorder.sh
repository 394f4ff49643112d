#!/usr/bin/env bash
# The recorder under load (BENCHMARKS.md, "Recorder"): a real-time run of
# the whole pipeline (plant simulator, sensor driver, controller, identifier,
# recorder) at RATE_HZ for DURATION_S of wall-clock time, while `exo fit`
# refits FIT_RECORDING... in a loop beside it. Prints the recorder's CPU share
# (from /proc), the messages it wrote, the samples it missed (sequence gaps,
# as it reports them in its log and in the file's `exo.drops` metadata), the
# controller's faults, and how many fits ran.
#
# Usage: tools/scripts/bench_recorder.sh RATE_HZ DURATION_S FIT_RECORDING...
# Build first: cargo build --release --workspace (or set EXO_BIN_DIR to a
# directory holding copies of the release binaries).
set -euo pipefail

rate=${1:?usage: bench_recorder.sh RATE_HZ DURATION_S FIT_RECORDING...}
duration=${2:?usage: bench_recorder.sh RATE_HZ DURATION_S FIT_RECORDING...}
shift 2
[ $# -gt 0 ] || { echo "bench_recorder.sh: give at least one recording for exo fit" >&2; exit 2; }
root=$(cd "$(dirname "$0")/../.." && pwd)
bin_dir=${EXO_BIN_DIR:-$root/target/release}
exo=$bin_dir/exo
[ -x "$exo" ] || { echo "bench_recorder.sh: $exo missing: cargo build --release --workspace" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cfg=$work/run.toml
instance=benchrec$$

# The default run file, made real-time at RATE_HZ, every experiment and
# period, stopped after DURATION_S.
sed -e "s|\"plants/|\"$root/configs/plants/|" \
    -e "s|\"subjects/|\"$root/configs/subjects/|" \
    -e "s|\"experiments.toml\"|\"$root/configs/experiments.toml\"|" \
    -e "s|^timing = \"lockstep\"|timing = \"realtime\"|" \
    -e "s|^rate_hz = 1000.0|rate_hz = $rate\nmax_sim_time_s = $duration|" \
    -e "s|^instance = \"exo\"|instance = \"$instance\"|" \
    -e "s|^output_dir = \"out/runs\"|output_dir = \"$work\"|" \
    -e "s|^experiments = \[1, 7\]|experiments = [1, 2, 3, 4, 5, 6, 7, 8, 9]|" \
    -e "/^periods = /d" \
    "$root/configs/default.toml" >"$cfg"
# The control path in SCHED_FIFO with locked memory on a CPU of its own, as
# on an exo computer (refusals are warned in the log): plant simulator,
# driver and controller on the last CPU (EXO_BENCH_RT_CPU), everything else
# -- the supervisor, identifier, recorder and `exo fit` -- confined to the
# other CPUs. EXO_BENCH_REALTIME=0 leaves all of this out.
#
# Why the CPU of its own: this machine's kernel is not preemptible
# (PREEMPT_NONE) and hands freed memory back to its host (free page
# reporting), so a process that allocates and frees hundreds of MB holds
# its CPU inside the kernel for milliseconds; measured here, a plain
# Python loop allocating 400 MB made the SCHED_FIFO control path miss its
# 5 ms deadline when it shared CPUs with it, and never when it did not.
ncpu=$(nproc)
rt_cpu=${EXO_BENCH_RT_CPU:-$((ncpu - 1))}
other_cpus=$(seq -s, 0 $((ncpu - 1)) | tr ',' '\n' | grep -vx "$rt_cpu" | paste -sd,)
confine=()
if [ "${EXO_BENCH_REALTIME:-1}" != 0 ]; then
    printf '\n[realtime]\nsched_fifo_priority = 80\nlock_memory = true\n' >>"$cfg"
    if [ -n "$other_cpus" ]; then
        printf 'plant_sim_cpu = %s\nsensor_driver_cpu = %s\ncontroller_cpu = %s\n' \
            "$rt_cpu" "$rt_cpu" "$rt_cpu" >>"$cfg"
        confine=(taskset -c "$other_cpus")
    fi
fi

echo "recorder bench: ${rate} Hz for ${duration} s, exo fit on $# recording(s) alongside" \
    "(control path on CPU $rt_cpu${other_cpus:+, the rest on CPUs $other_cpus})"
"${confine[@]}" "$exo" run "$cfg" --no-report >"$work/run.log" 2>&1 &
run_pid=$!

# The recorder's process, once the supervisor has started it.
rec_pid=
for _ in $(seq 100); do
    rec_pid=$(pgrep -f "exo-recorder --config $cfg" || true)
    [ -n "$rec_pid" ] && break
    sleep 0.1
done
[ -n "$rec_pid" ] || { cat "$work/run.log" >&2; echo "recorder never started" >&2; exit 1; }
start_ns=$(date +%s%N)
# utime + stime of the recorder (clock ticks), sampled twice a second while it lives.
(
    while [ -r "/proc/$rec_pid/stat" ]; do
        awk '{print $14 + $15}' "/proc/$rec_pid/stat" >"$work/ticks.new" 2>/dev/null &&
            mv "$work/ticks.new" "$work/ticks" && date +%s%N >"$work/t_end"
        sleep 0.5
    done
) &
fits=0
fit_s=0
while kill -0 "$run_pid" 2>/dev/null; do
    f0=$(date +%s%N)
    "${confine[@]}" "$exo" fit "$@" --json >/dev/null 2>&1 || true
    f1=$(date +%s%N)
    if kill -0 "$run_pid" 2>/dev/null; then
        fits=$((fits + 1))
        fit_s=$((fit_s + (f1 - f0) / 1000000))
    fi
done
wait "$run_pid" && rc=0 || rc=$?
sleep 1
ticks=$(cat "$work/ticks" 2>/dev/null || echo 0)
rec_end_ns=$(cat "$work/t_end" 2>/dev/null || echo "$start_ns")
hz=$(getconf CLK_TCK)
wall_s=$(awk -v a="$start_ns" -v b="${rec_end_ns:-$start_ns}" 'BEGIN{print (b-a)/1e9}')
cpu_s=$(awk -v t="$ticks" -v hz="$hz" 'BEGIN{print t/hz}')
echo "exo run exit status: $rc"
grep -E "recorder: [0-9]+ messages" "$work/run.log" | sed 's/^/  /' || echo "  (no recorder summary: see the log below)"
grep -E "sequence gaps" "$work/run.log" | sed 's/^/  /' || true
grep -E "missed|fault|safe state|deadline|realtime|SCHED" "$work/run.log" | grep -v "sequence gaps" | sed 's/^/  /' | head -20 || true
# The plant's final count of missed real-time deadlines (past the cut above).
grep -E "plant-sim: [0-9]+ missed real-time deadlines" "$work/run.log" | sed 's/^/  /' || true
awk -v c="$cpu_s" -v w="$wall_s" 'BEGIN{printf "  recorder CPU: %.1f s over %.1f s of its life (%.2f %% of one core)\n", c, w, 100*c/w}'
echo "  exo fit alongside: $fits complete fits, $(awk -v n="$fits" -v s="$fit_s" 'BEGIN{if(n>0) printf "%.2f", s/n/1000; else print "-"}') s each"
if [ "$rc" -ne 0 ]; then
    tail -30 "$work/run.log" >&2
    exit "$rc"
fi
