# Everyday tasks; each is a thin cargo call.

# Run the whole test suite.
test:
    cargo test --workspace

# Tests including the OpenBLAS backend (needs libopenblas-dev).
test-openblas:
    cargo test --workspace --features openblas

# Long property-test runs.
proptest-long:
    cargo test --workspace --features slow-proptests

# Criterion benches (backends, assembly, culling, one load step).
bench:
    cargo bench --features openblas

# Run the bundled sphere scene and write out/sphere/.
demo:
    cargo run --release -p fibfluid-cli -- run fixtures/scenes/sphere.toml --out out/sphere

# Quick backend comparison on this machine.
bench-quick:
    cargo run --release -p fibfluid-cli --features openblas -- bench --sizes 250,1000

# API docs.
docs:
    cargo doc --workspace --no-deps

# Everything CI runs.
ci:
    bash .ci/run
