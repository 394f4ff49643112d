#!/usr/bin/env bash
# Mutation testing of exo's science and safety code with cargo-mutants
# (issue 23). Each crate's mutants are tested by that crate's own tests.
#
#   tools/scripts/mutants.sh                      # every crate, whole (slow: hours on 2 cores)
#   tools/scripts/mutants.sh --shard 2/8          # one shard of every crate
#   tools/scripts/mutants.sh --fresh 12 [--seed S] # per crate, a shard k/12 not measured before
#                                                 # (k drawn with seed S, printed and recorded;
#                                                 # the shards in score.tsv are skipped): a score
#                                                 # from mutants whose survivors nobody has seen
#   tools/scripts/mutants.sh --crate exo-impedance --shard 1/4
#   tools/scripts/mutants.sh --in-diff main       # only code changed since main (the habit before a commit)
#   tools/scripts/mutants.sh --crate exo-impedance --file shared/impedance/src/ftest.rs \
#       -- --in-place -- --lib --test it   # one file; args after -- go to cargo mutants
#                                          # (after a second --, to cargo test: here the unit
#                                          # tests and the crate's one integration-test binary)
#
# Writes per crate  $OUT/<crate>/mutants.out/  (cargo-mutants' own files)
# and the scores to $OUT/score.tsv: crate, shard, caught, missed, timeout,
# unviable, and caught / (caught + missed + timeout) in percent.
# OUT defaults to target/mutants. Not part of .ci/run (too slow on 2 cores).
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
cd "$root"

# The science and safety code: crate and the files of it that are mutated.
declare -A FILES=(
  [exo-impedance]="shared/impedance/src/*.rs shared/impedance/src/*/*.rs"
  [exo-identifier]="services/identifier/src/*.rs"
  [exo-controller]="services/controller/src/*.rs services/controller/src/*/*.rs"
  [exo-diagnose]="tools/diagnose/src/*.rs tools/diagnose/src/*/*.rs"
  [exo-sensor-driver]="services/sensor-driver/src/*.rs services/sensor-driver/src/*/*.rs"
  [exo-config]="shared/config/src/run.rs shared/config/src/run/*.rs shared/config/src/subject.rs shared/config/src/experiments.rs shared/config/src/ethercat.rs"
)
ORDER=(exo-impedance exo-identifier exo-controller exo-diagnose exo-sensor-driver exo-config)

shard="" fresh="" seed="" crates=() files=() base="" out="${MUTANTS_OUT:-$root/target/mutants}" extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --shard) shard="$2"; shift 2 ;;
    --fresh) fresh="$2"; shift 2 ;;
    --seed) seed="$2"; shift 2 ;;
    --crate) crates+=("$2"); shift 2 ;;
    --file) files+=("$2"); shift 2 ;;
    --in-diff) base="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --) shift; extra=("$@"); break ;;
    -h|--help) sed -n '2,22p' "$0"; exit 0 ;;
    *) echo "mutants.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
[ ${#crates[@]} -gt 0 ] || crates=("${ORDER[@]}")
if [ -n "$fresh" ]; then
  [ -z "$shard" ] || { echo "mutants.sh: --fresh and --shard exclude each other" >&2; exit 2; }
  [[ "$fresh" =~ ^[1-9][0-9]*$ ]] || { echo "mutants.sh: --fresh N: N must be a positive integer, got $fresh" >&2; exit 2; }
  [ -n "$seed" ] || seed=$(od -An -N4 -tu4 /dev/urandom | tr -d ' ')
  [[ "$seed" =~ ^[0-9]+$ ]] || { echo "mutants.sh: --seed S: S must be a non-negative integer, got $seed" >&2; exit 2; }
fi
for c in "${crates[@]}"; do
  [ -n "${FILES[$c]+x}" ] || { echo "mutants.sh: $c is not one of: ${ORDER[*]}" >&2; exit 2; }
done

# cargo-mutants, installed by this script when missing.
if ! cargo mutants --version >/dev/null 2>&1; then
  echo "mutants.sh: installing cargo-mutants (cargo install cargo-mutants --locked)" >&2
  cargo install cargo-mutants --locked
fi

# Incremental compilation for the mutants' builds (the dev profile turns it
# off, for CI's cold builds): a mutant changes one function, and rebuilding
# exo-diagnose's library and test binaries after such a change took 28 s
# without it and 6.5 s with it (docs/testing.md, "Mutation runs that fit
# the machine"). CARGO_INCREMENTAL=0 in the caller's environment keeps it off.
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-1}"

mkdir -p "$out"
score="$out/score.tsv"
[ -f "$score" ] || printf 'crate\tshard\tcaught\tmissed\ttimeout\tunviable\tscore_pct\n' >"$score"
diff_file=""
if [ -n "$base" ]; then
  diff_file="$out/in-diff.patch"
  git diff "$base" -- >"$diff_file"
fi

count() { if [ -f "$1" ]; then grep -c . "$1" || true; else echo 0; fi; }

# A shard k/N of crate $1 not yet in score.tsv, drawn with $seed (and the
# crate's name, so crates draw differently); empty when all N are measured.
fresh_shard() {
  local c=$1 used k i
  used=$(awk -F'\t' -v c="$c" -v n="$fresh" '$1 == c { split($2, a, " "); split(a[1], b, "/"); if (b[2] == n) print b[1] }' "$score" | sort -un)
  local free=()
  for ((k = 0; k < fresh; k++)); do
    grep -qx "$k" <<<"$used" || free+=("$k")
  done
  [ ${#free[@]} -gt 0 ] || return 0
  i=$(( ($(printf '%s' "$seed$c" | cksum | cut -d' ' -f1)) % ${#free[@]} ))
  echo "${free[$i]}/$fresh"
}

for c in "${crates[@]}"; do
  label=""
  if [ -n "$fresh" ]; then
    shard=$(fresh_shard "$c")
    if [ -z "$shard" ]; then
      echo "mutants.sh: $c: every shard of $fresh has been measured; take a larger N" >&2
      continue
    fi
    label=" fresh seed $seed"
    echo "mutants.sh: $c: fresh shard $shard (seed $seed)" >&2
  fi
  args=(mutants --package "$c" --output "$out/$c" --no-shuffle)
  if [ ${#files[@]} -gt 0 ]; then
    for f in "${files[@]}"; do args+=(--file "$f"); done
  else
    for f in ${FILES[$c]}; do args+=(--file "$f"); done
  fi
  [ -n "$shard" ] && args+=(--shard "$shard")
  [ -n "$diff_file" ] && args+=(--in-diff "$diff_file")
  echo "mutants.sh: cargo ${args[*]} ${extra[*]:-}" >&2
  # cargo-mutants exits 2 when mutants are missed, 3 on timeouts: not errors here.
  set +e
  cargo "${args[@]}" "${extra[@]}"
  rc=$?
  set -e
  case $rc in 0|2|3) ;; *) echo "mutants.sh: cargo mutants failed on $c (exit $rc)" >&2; exit $rc ;; esac
  d="$out/$c/mutants.out"
  caught=$(count "$d/caught.txt"); missed=$(count "$d/missed.txt")
  timeout=$(count "$d/timeout.txt"); unviable=$(count "$d/unviable.txt")
  viable=$((caught + missed + timeout))
  pct=$(awk -v c="$caught" -v v="$viable" 'BEGIN { if (v > 0) printf "%.1f", 100 * c / v; else print "n/a" }')
  printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$c" "${shard:-whole}${label}${base:+ in-diff $base}" \
    "$caught" "$missed" "$timeout" "$unviable" "$pct" >>"$score"
  echo "mutants.sh: $c: caught $caught, missed $missed, timeout $timeout, unviable $unviable ($pct % of viable)" >&2
  if [ "$missed" -gt 0 ]; then sed 's/^/  missed: /' "$d/missed.txt" >&2; fi
done
echo "mutants.sh: scores in $score" >&2
