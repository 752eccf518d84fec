#!/usr/bin/env bash
# CI for the Python package: installs it as a user does (a fresh virtual environment and
# the one line `pip install ./crates/python`, which builds it with maturin; here at
# opt-level 1, below), then runs its pytest suite. Exits non-zero on any failure, and
# when pytest collects no test.
#
# The suite compares a run with the command line's `deformed.obj`. The command line is
# taken from `cargo test --workspace --no-run`: run after `.ci/run`'s `cargo test
# --workspace`, that is the binary already built, so nothing is compiled twice. Set
# FIBFLUID_CLI to a `fibfluid` binary to use that one instead.
#
# Needs: Python >= 3.9 with venv, cargo (Rust 1.95), network access to PyPI (maturin, numpy,
# pytest, and dask and distributed for the sweep on a local Dask cluster).
set -euo pipefail
cd "$(dirname "$0")/../.."

# The crate is outside the workspace (docs/python.md): the root's `cargo fmt --all` and
# `cargo clippy --workspace` do not see it. `--locked`: its Cargo.lock must be up to date.
echo "== rustfmt and clippy of crates/python"
cargo fmt --manifest-path crates/python/Cargo.toml -- --check
cargo clippy --manifest-path crates/python/Cargo.toml --all-targets --features testing --locked -- -D warnings

python=${PYTHON:-python3}
venv=$(mktemp -d "${TMPDIR:-/tmp}/fibfluid-py.XXXXXX")
trap 'rm -rf "$venv"' EXIT

echo "== python package: fresh venv ($("$python" --version 2>&1)) in $venv"
if ! "$python" -m venv "$venv"; then
  # Debian's system Python keeps venv in a package of its own.
  if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null 2>&1; then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv >/dev/null
    "$python" -m venv "$venv"
  else
    echo "error: $python -m venv failed (install python3-venv)" >&2
    exit 1
  fi
fi
# The package as a user installs it, plus the `testing` feature: the test hook
# `Body._fail_next_refreshes` (maturin's PEP 517 backend reads its arguments from
# MATURIN_PEP517_ARGS).
# Optimized at level 1 (CARGO_PROFILE_RELEASE_OPT_LEVEL): the same code as a user's
# release build, compiled in about 3.5 minutes instead of 8 on two cores, its tests about
# 10 s slower. A user's `pip install` keeps the release profile.
echo "== pip install ./crates/python pytest numpy dask distributed (features: testing; opt-level 1)"
CARGO_PROFILE_RELEASE_OPT_LEVEL=${CARGO_PROFILE_RELEASE_OPT_LEVEL:-1} MATURIN_PEP517_ARGS="--features testing" "$venv/bin/python" -m pip install --disable-pip-version-check --progress-bar off ./crates/python pytest numpy dask distributed

if [ -z "${FIBFLUID_CLI:-}" ]; then
  echo "== the command line to compare with (cargo test --workspace --no-run)"
  FIBFLUID_CLI=$(cargo test --workspace --no-run --message-format=json-render-diagnostics |
    "$venv/bin/python" -c '
import json, sys
found = ""
for line in sys.stdin:  # read it all: cargo must not write into a closed pipe
    m = json.loads(line)
    t = m.get("target", {})
    if m.get("reason") == "compiler-artifact" and t.get("name") == "fibfluid" and t.get("kind") == ["bin"]:
        found = m.get("executable") or found
print(found)
')
  if [ -z "$FIBFLUID_CLI" ]; then
    echo "error: cargo built no fibfluid binary" >&2
    exit 1
  fi
  export FIBFLUID_CLI
fi
echo "   FIBFLUID_CLI=$FIBFLUID_CLI"

echo "== pytest crates/python/tests"
status=0
"$venv/bin/python" -m pytest crates/python/tests -q -p no:cacheprovider || status=$?
if [ "$status" -eq 5 ]; then
  echo "error: pytest collected no test" >&2
  exit 1
fi
exit "$status"
