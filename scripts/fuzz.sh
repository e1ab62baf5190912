#!/usr/bin/env bash
# Coverage-guided fuzzing of every coif parser (cargo-fuzz + libFuzzer, fuzz/).
#
#   scripts/fuzz.sh                 # each target until 1M executions or 30 min, whichever first
#   FUZZ_SECONDS=20 FUZZ_RUNS=0 scripts/fuzz.sh      # each target for 20 s
#   FUZZ_BUILD=dev scripts/fuzz.sh  # unoptimised targets: built in half the time, run slower
#   scripts/fuzz.sh npy manifest    # only these targets
#   FUZZ_JOBS=1 scripts/fuzz.sh     # one target at a time (default: one per core)
#
# Seeds come from the repo's test data and a small run of coif itself (never from ../shared).
# A crash stops the script with the target's name; libFuzzer leaves the input in
# fuzz/artifacts/<target>/: fix the parser and copy the input to fuzz/regressions/<target>/,
# which tests/it/fuzz_regressions.rs replays on every `cargo test`.
# The execution count of each target is printed and appended to fuzz/target/fuzz-stats.tsv.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_PER_TARGET="${FUZZ_SECONDS:-1800}"
RUNS="${FUZZ_RUNS:-1000000}"
# CI's brief runs use `dev`: the optimised build of coif and its ~190 dependencies with
# coverage instrumentation took 8 min on 2 cores, the unoptimised one under 4.
case "${FUZZ_BUILD:-release}" in
    release) PROFILE=-O ;;
    dev) PROFILE=--dev ;;
    *) echo "fuzz: FUZZ_BUILD must be release or dev, not '$FUZZ_BUILD'" >&2; exit 2 ;;
esac

if ! command -v cargo-fuzz >/dev/null; then
    cargo install cargo-fuzz --locked --version 0.13.2
fi
# `-s none` (no sanitizer) needs no nightly flags: the stable toolchain builds the targets.

mapfile -t ALL < <(sed -n '/^pub const TARGETS/,/];/p' src/testing/fuzz.rs | grep -o '"[a-z_]*"' | tr -d '"')
TARGETS=("$@")
[ ${#TARGETS[@]} -eq 0 ] && TARGETS=("${ALL[@]}")

# Seeds: the repo's own files of each format, and what a 96² synthetic run writes.
seeds=fuzz/target/seeds
if [ ! -e "$seeds/done" ]; then
    rm -rf "$seeds" && mkdir -p "$seeds"
    cargo build --release --bin coif
    coif=target/release/coif
    [ -n "${CARGO_TARGET_DIR:-}" ] && coif="$CARGO_TARGET_DIR/release/coif"
    run="$seeds/run"
    "$coif" synth --out "$run/case" --style long --size 96 --seed 1 >/dev/null
    "$coif" model --image "$run/case/image.png" --strokes "$run/case/strokes.json" \
        --mask "$run/case/mask.png" --landmarks "$run/case/landmarks.json" \
        --out "$run/model" --backend cpu >/dev/null
    "$coif" sketch --image "$run/case/image.png" --mask "$run/case/mask.png" \
        --out "$run/sketch" --backend cpu >/dev/null
    "$coif" convert tests/data/strands/Bangs_100.hair "$run/bangs.obj" >/dev/null
    "$coif" convert tests/data/strands/Bangs_100.hair "$run/bangs.ply" >/dev/null
    printf '%s\n' \
        '# two jobs' \
        '{"id": "p001", "image": "a.png", "strokes": "a.json", "landmarks": "a_lm.json", "out": "out/p001", "steps": ["model", "render"], "render": {"yaw": 25}}' \
        '{"id": "p002", "image": "b.png", "mask": "b_mask.png", "out": "out/p002", "steps": ["sketch", "synth-hair"], "synth-hair": {"seed": 3}}' \
        >"$run/jobs.jsonl"
    seed() { local t=$1; shift; mkdir -p "$seeds/$t"; for f in "$@"; do cp "$f" "$seeds/$t/$(echo "$f" | tr / _)"; done; }
    seed strands_hair tests/data/strands/Bangs_100.hair "$run/model/strands.hair"
    seed strands_data tests/data/strands/Bangs_100.data
    seed strands_ply tests/data/strands/Bangs_100_ascii.ply tests/data/strands/Curly_100.ply "$run/bangs.ply"
    seed strands_obj "$run/bangs.obj"
    seed strokes_json assets/astronaut_strokes.json assets/astronaut_comb.json assets/astronaut_cut.json tests/data/carphone_strokes.json
    seed landmarks_json "$run/case/landmarks.json"
    seed labelme_json tests/data/labelme_strokes.json
    seed svg_strokes tests/data/svg_strokes.svg
    seed sketch_czs "$run/sketch/hair.czs"
    seed sketch_json "$run/sketch/sketch.json"
    seed sketch_svg "$run/sketch/sketch.svg" tests/data/sketch/inkscape/*.svg
    seed npy "$run/model/direction.npy" "$run/case/gt_theta.npy"
    seed model_json "$run/model/model.json"
    seed manifest "$run/jobs.jsonl"
    touch "$seeds/done"
fi

stats=fuzz/target/fuzz-stats.tsv
mkdir -p fuzz/target
# Each libFuzzer process runs on one core: FUZZ_JOBS targets (default: one per core) run at
# once, after one build of every target (runs started together would queue on cargo's lock;
# the targets share the instrumented library, so building all costs little more than one).
JOBS="${FUZZ_JOBS:-$(nproc)}"
(cd fuzz && cargo fuzz build -s none $PROFILE)

run_target() {
    local t=$1 corpus="fuzz/corpus/$1" log="fuzz/target/fuzz-$1.log"
    mkdir -p "$corpus" "fuzz/artifacts/$t"
    # Regressions join the corpus so every run re-checks them.
    echo "fuzz: $t (up to $RUNS runs or $SECONDS_PER_TARGET s)"
    (cd fuzz && cargo fuzz run -s none $PROFILE "$t" "corpus/$t" "../$seeds/$t" \
        $( [ -d "regressions/$t" ] && echo "regressions/$t" ) -- \
        -runs="$( [ "$RUNS" = 0 ] && echo -1 || echo "$RUNS")" \
        -max_total_time="$SECONDS_PER_TARGET" -max_len=65536 -rss_limit_mb=2048 \
        -timeout=10 -print_final_stats=1) >"$log" 2>&1 || {
        tail -40 "$log"
        echo "fuzz: $t FAILED; the input is in fuzz/artifacts/$t/ and the log in $log" >&2
        return 1
    }
    local execs secs cov
    execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
    secs=$(grep -o 'Done [0-9]* runs in [0-9]* second' "$log" | grep -o 'in [0-9]*' | grep -o '[0-9]*' | tail -1)
    cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*')
    echo "fuzz: $t: ${execs:-?} executions in ${secs:-?} s, coverage ${cov:-?} edges, no crash"
    printf '%s\t%s\t%s\t%s\t%s\n' "$(date -u +%FT%TZ)" "$t" "${execs:-?}" "${secs:-?}" "${cov:-?}" >>"$stats"
}

# A failed target leaves a mark: `wait -n` may miss the status of a job that ended earlier.
rm -f fuzz/target/failed-*
for t in "${TARGETS[@]}"; do
    while [ "$(jobs -rp | wc -l)" -ge "$JOBS" ]; do wait -n || true; done
    { run_target "$t" || touch "fuzz/target/failed-$t"; } &
done
wait
if compgen -G 'fuzz/target/failed-*' >/dev/null; then
    echo "fuzz: failed: $(cd fuzz/target && ls failed-* | sed 's/^failed-//' | tr '\n' ' ')" >&2
    exit 1
fi
