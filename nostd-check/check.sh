#!/usr/bin/env bash
# Links otbake-runtime into a no_std binary with no global allocator and panic=abort, then runs it.
# Exits non-zero (with the linker's message) if the runtime needs an allocator or std.
set -euo pipefail
cd "$(dirname "$0")/.."
# Every crate of this build uses panic=abort; a separate target dir keeps the main build cache intact.
# no_std binaries link without default libraries: -lc brings memcpy/memset and process start-up only.
CARGO_PROFILE_RELEASE_PANIC=abort CARGO_PROFILE_RELEASE_DEBUG=false \
  cargo rustc -p otbake-nostd-check --release --target-dir target/nostd-check -- -C link-arg=-lc
# Lints too: the crate cannot be checked with the workspace (it needs panic=abort everywhere).
CARGO_PROFILE_RELEASE_PANIC=abort cargo clippy -p otbake-nostd-check --release --target-dir target/nostd-check -- -D warnings
bin=target/nostd-check/release/otbake-nostd-check
test -x "$bin"
# Zeroed bytes are not an archive: the runtime must refuse them with an error (exit 3), not crash.
set +e
"$bin"
status=$?
set -e
if [ "$status" -ne 3 ]; then
  echo "nostd-check: expected exit 3 (archive refused), got $status" >&2
  exit 1
fi
# The runtime's queries are really in the binary (not optimized away).
if command -v nm >/dev/null; then
  syms=$(nm -C "$bin" | grep -c otbake_runtime || true)
  echo "nostd-check: linked $(stat -c %s "$bin") bytes, $syms otbake_runtime symbols, no allocator"
fi
