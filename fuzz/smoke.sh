#!/usr/bin/env bash
# Fuzz smoke run (CI): builds every cargo fuzz target and runs each for FUZZ_SECONDS (default
# 10) from its seeds, then the atheris harnesses the same way. Any crash fails the run and
# leaves its input in $FUZZ_WORK (default: a new temporary directory). Needs the nightly
# toolchain; installs cargo-fuzz (crates.io) and atheris (PyPI) when they are missing.
# Coverage without a sanitizer: the code is safe Rust, the checks that matter are panics,
# overflow (on in fuzz/Cargo.toml), timeouts and memory, and the build is twice as fast.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${FUZZ_SECONDS:-10}
work=${FUZZ_WORK:-$(mktemp -d -t dynmesh-fuzz-XXXXXX)}
command -v cargo-fuzz >/dev/null || cargo install --quiet --locked cargo-fuzz
python -c "import atheris" 2>/dev/null || pip install --quiet atheris
cargo run --quiet --release -p dynmesh --features fuzzing --example fuzz_seeds -- "$work/rust"
(cd fuzz && cargo +nightly fuzz build -O --sanitizer none)
for target in stream base motion refresh uv coef; do
    echo "fuzz smoke: $target (${seconds} s)"
    log="$work/rust-$target.log"
    (cd fuzz && cargo +nightly fuzz run -O --sanitizer none "$target" "$work/rust/$target" -- \
        -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=10 -artifact_prefix="$work/" -print_final_stats=1) \
        > "$log" 2>&1 || { tail -n 40 "$log"; exit 1; }
    grep -E "^Done|stat::peak_rss_mb" "$log"
done
python fuzz/python/fuzz_readers.py seeds "$work/python" > "$work/python-seeds.log" 2>&1 || { tail -n 40 "$work/python-seeds.log"; exit 1; }
for target in obj ply mtl texture; do
    echo "fuzz smoke: python $target (${seconds} s)"
    python fuzz/python/fuzz_readers.py "$target" -max_total_time="$seconds" -artifact_prefix="$work/" "$work/python/$target" \
        > "$work/python-$target.log" 2>&1 || { tail -n 40 "$work/python-$target.log"; exit 1; }
    grep -E "^Done" "$work/python-$target.log"
done
