#!/usr/bin/env bash
# Coverage-guided fuzzing of springbake's readers with AFL++ through afl.rs, on the stable
# toolchain (issue 17, item 7). Installs cargo-afl if missing, builds the targets of
# fuzz/src/lib.rs with AFL's instrumentation, seeds each from ../shared/corpus, examples/ and
# the kept corpus, fuzzes each for SECONDS, then keeps the minimised queue in
# fuzz/corpus/<target>/ (replayed by `cargo test -p springbake-fuzz` in CI). Findings
# (crashes, hangs) are copied to target/fuzz/findings/<target>/ and listed at the end.
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET=900] [TARGET...]   (targets: gltf obj scene usd_mesh)
#   scripts/fuzz.sh keep [TARGET...]   only minimise the last run's queues into fuzz/corpus
set -euo pipefail
cd "$(dirname "$0")/.."
keep_only=false
if [ "${1:-}" = keep ]; then
  keep_only=true
  shift
fi
secs=900
if [ "$keep_only" = false ] && [ $# -gt 0 ]; then
  secs=$1
  shift
fi
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(gltf obj scene usd_mesh)

command -v cargo-afl >/dev/null || cargo install cargo-afl --locked
# Builds AFL++ for this toolchain once; says so and fails harmlessly when it already has.
cargo afl config --build >/dev/null 2>&1 || true
(cd fuzz/afl && cargo afl build --release)
bin=fuzz/afl/target/release
work=target/fuzz
mkdir -p "$work/out" "$work/cmin" "$work/findings"

seed() { # target -> fills $work/seeds/<target>
  local t=$1 dir=$work/seeds/$1
  rm -rf "$dir" && mkdir -p "$dir"
  cp fuzz/corpus/"$t"/* "$dir"/ 2>/dev/null || true
  local pattern
  case $t in
    gltf) pattern='.*\.\(gltf\|glb\)' ;;
    obj) pattern='.*\.obj' ;;
    scene) pattern='.*\.toml' ;;
    *) pattern='' ;;
  esac
  if [ -n "$pattern" ]; then
    find ../shared/corpus examples -regex "$pattern" -size -64k -type f -print0 |
      while IFS= read -r -d '' f; do cp "$f" "$dir/$(echo "$f" | tr '/' '_')"; done
  fi
  # AFL needs at least one seed.
  [ -n "$(ls -A "$dir")" ] || head -c 64 /dev/urandom > "$dir/random"
}

# afl-cmin.bash (the Python afl-cmin finds no coverage in afl.rs's persistent binaries).
afl_bin=$(ls -d "$HOME"/.local/share/afl.rs/*/afl.rs-*/afl/bin 2>/dev/null | tail -1)

keep() { # target: minimise its queue into fuzz/corpus/<target>, named by content hash
  local t=$1 out=$work/out/$1/default/queue
  [ -d "$out" ] || return 0
  rm -rf "$work/cmin/$t"
  AFL_SKIP_CPUFREQ=1 AFL_PATH="$afl_bin" PATH="$afl_bin:$PATH" \
    "$afl_bin/afl-cmin.bash" -i "$out" -o "$work/cmin/$t" -t 10000 -m 2048 -- "$bin/$t" \
    > "$work/$t.cmin.log" 2>&1 || true
  if [ -n "$(ls -A "$work/cmin/$t" 2>/dev/null)" ]; then
    mkdir -p fuzz/corpus/"$t"
    # Cases kept before (e.g. fixed findings) stay.
    for f in "$work/cmin/$t"/*; do cp "$f" fuzz/corpus/"$t"/"$(sha1sum "$f" | cut -c1-16)"; done
  fi
  echo "   $t: kept $(ls fuzz/corpus/"$t" 2>/dev/null | wc -l) cases"
}

if [ "$keep_only" = true ]; then
  for t in "${targets[@]}"; do keep "$t"; done
  exit 0
fi

for t in "${targets[@]}"; do
  seed "$t"
  out=$work/out/$t
  rm -rf "$out"
  echo "== fuzzing $t for $secs s"
  AFL_SKIP_CPUFREQ=1 AFL_NO_UI=1 AFL_I_DONT_CARE_ABOUT_MISSING_CRASHES=1 \
    AFL_NO_AFFINITY=1 AFL_SKIP_CRASHES=1 \
    cargo afl fuzz -i "$work/seeds/$t" -o "$out" -V "$secs" -t 10000 -m 2048 \
    "$bin/$t" > "$work/$t.log" 2>&1 || true
  grep -E "execs_done|execs_per_sec|corpus_count|saved_crashes|saved_hangs|bitmap_cvg" \
    "$out/default/fuzzer_stats" || true
  mkdir -p "$work/findings/$t"
  cp "$out"/default/crashes/id* "$out"/default/hangs/id* "$work/findings/$t"/ 2>/dev/null || true
  echo "   findings: $(ls "$work/findings/$t" | wc -l)"
  keep "$t"
done
