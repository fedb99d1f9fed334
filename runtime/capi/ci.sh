#!/usr/bin/env bash
# The C ABI's checks, run by .ci/run (and by hand: `bash runtime/capi/ci.sh` from anywhere):
#   1. include/otbake.h is what cbindgen 0.24.3 generates from the crate (fails when stale);
#   2. small archives are baked here, examples/c_expected.rs writes the Rust runtime's answers,
#      and the C test (c/*.c, system `cc`) checks them bit for bit plus every bad-input refusal,
#      once plain and once with -fsanitize=address,undefined;
#   3. the C++ engine example (c/engine.cpp, system `c++`) maps the archives and renders frames,
#      splatting from the blend and from a prepared blend per frame: the same bytes;
#   4. the README's C example compiles as written and runs.
# Needs ../shared/data beside the repository (the bake's inputs). Fails loudly on the first error.
set -euo pipefail
cd "$(dirname "$0")/../.."
root=$PWD
capi=runtime/capi

if ! command -v cbindgen >/dev/null 2>&1; then
  echo "== installing cbindgen (Debian's, 0.24.3)"
  (apt-get install -y -qq cbindgen || (apt-get update -qq && apt-get install -y -qq cbindgen)) >/dev/null
fi
if [ "$(cbindgen --version)" != "cbindgen 0.24.3" ]; then
  echo "error: the checked-in otbake.h is cbindgen 0.24.3's; found $(cbindgen --version): install 0.24.3 (Debian bookworm's apt package) so the staleness check compares like with like" >&2
  exit 1
fi
for tool in cc c++; do
  command -v "$tool" >/dev/null 2>&1 || { echo "error: the C ABI checks need \`$tool\` (apt-get install build-essential)" >&2; exit 1; }
done

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

echo "== otbake.h is current (cbindgen)"
cbindgen -q --config $capi/cbindgen.toml --crate otbake-capi --output "$tmp/otbake.h" $capi
if ! diff -u $capi/include/otbake.h "$tmp/otbake.h"; then
  echo "error: $capi/include/otbake.h is stale: regenerate it with" >&2
  echo "  cbindgen --config $capi/cbindgen.toml --crate otbake-capi --output $capi/include/otbake.h $capi" >&2
  exit 1
fi

echo "== building the C ABI, the baker and the expected-values writer"
# Target selections apply to every package named: the baker's binary and the library's artifacts
# come from a plain build, the example from a second one.
cargo build -q -p otbake -p otbake-capi
cargo build -q -p otbake-capi --example c_expected
lib=target/debug/libotbake_capi.a

echo "== baking small archives (two proxies of 2D shapes, one BRDF bake)"
data=$(cd ../shared/data && pwd)
shapes() { # NAME SEED
  cat <<EOF
[output]
dir = "$1"
[proxy]
kind = "gaussian"
samples = 400
seed = $2
[solver]
kind = "exact"
[[input]]
name = "redcross"
path = "$data/shapes/redcross.png"
density = "inverted"
[[input]]
name = "tooth"
path = "$data/shapes/tooth.png"
density = "inverted"
[[input]]
name = "heart"
path = "$data/shapes/heart.png"
density = "inverted"
EOF
}
shapes a 0 >"$tmp/a.toml"
shapes b 1 >"$tmp/b.toml"
cat >"$tmp/brdf.toml" <<EOF
[output]
dir = "brdf"
[proxy]
kind = "gaussian"
sigma = 0.1667
samples = 400
seed = 0
[solver]
kind = "exact"
[brdf]
resolution = 12
[[input]]
name = "cayman"
path = "$data/brdfs/cornell_cayman.brdf"
[[input]]
name = "garnet_red"
path = "$data/brdfs/cornell_garnet_red.brdf"
EOF
target/debug/otbake bake "$tmp/a.toml" "$tmp/b.toml" "$tmp/brdf.toml" >"$tmp/bake.log" 2>&1 || { cat "$tmp/bake.log"; exit 1; }
a="$tmp/a/proxy.otb $tmp/a/redcross.otb $tmp/a/tooth.otb $tmp/a/heart.otb"
brdf="$tmp/brdf/proxy.otb $tmp/brdf/cayman.otb $tmp/brdf/garnet_red.otb"
# shellcheck disable=SC2086
target/debug/examples/c_expected "$tmp/expected.txt" $a -- $brdf
test_args=("$tmp/expected.txt" "$tmp/a/proxy.otb" "$tmp/a/redcross.otb" "$tmp/b/tooth.otb" "$tmp/brdf/proxy.otb" "$tmp/brdf/cayman.otb")

cflags=(-std=c11 -Wall -Wextra -Werror -pedantic -O1 -g -I $capi/include -I $capi/c)
libs=(-lm -lpthread -ldl)
csrc=($capi/c/main.c $capi/c/expected.c $capi/c/prepared.c $capi/c/bad_input.c)

echo "== C test (cc $(cc -dumpversion))"
cc "${cflags[@]}" "${csrc[@]}" $lib "${libs[@]}" -o "$tmp/c_test"
"$tmp/c_test" "${test_args[@]}"

echo "== C test with -fsanitize=address,undefined"
san=(-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
cc "${cflags[@]}" "${san[@]}" "${csrc[@]}" $lib "${libs[@]}" -o "$tmp/c_test_san"
ASAN_OPTIONS=abort_on_error=1:detect_leaks=1 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
  "$tmp/c_test_san" "${test_args[@]}"

echo "== C++ engine example (c++ $(c++ -dumpversion)), against the shared library"
c++ -std=c++17 -Wall -Wextra -Werror -O2 -I $capi/include $capi/c/engine.cpp \
  -L target/debug -lotbake_capi -Wl,-rpath,"$root/target/debug" -lpthread -o "$tmp/engine"
# shellcheck disable=SC2086
"$tmp/engine" "$tmp/frame" 3 96 $a
# shellcheck disable=SC2086
"$tmp/engine" --mode prepared "$tmp/prepared" 3 96 $a
for f in 000 001 002; do
  head -c 2 "$tmp/frame-$f.ppm" | grep -q P6 || { echo "error: frame $f is not a PPM" >&2; exit 1; }
  cmp "$tmp/frame-$f.ppm" "$tmp/prepared-$f.ppm" || { echo "error: frame $f differs between the blend and prepared modes" >&2; exit 1; }
done

echo "== the README's C example compiles as written and runs"
sed -n '/<!-- c-example:begin -->/,/<!-- c-example:end -->/p' README.md | sed '1,2d;$d' | sed '$d' >"$tmp/readme.c"
[ "$(wc -l <"$tmp/readme.c")" -ge 5 ] || { echo "error: README.md has no C example between the c-example markers" >&2; exit 1; }
cc -std=c11 -Wall -Wextra -Werror -I $capi/include "$tmp/readme.c" $lib "${libs[@]}" -o "$tmp/readme"
"$tmp/readme" "$tmp/a/proxy.otb" "$tmp/a/redcross.otb" "$tmp/a/tooth.otb"

echo "C ABI checks passed"
