#!/usr/bin/env bash
# Builds the emulated drive with our plant (tools/plant-drive) into DIR:
# DIR/exo_plant_drive and DIR/slave_configs/ (the vendor's ESI and our slave file).
# Usage: build.sh DIR [LIB]
#   LIB: libexo_plant_drive.a when already built (the tests pass theirs);
#        otherwise `cargo build -p exo-plant-drive` builds it (in $CARGO_TARGET_DIR, or target/).
# Needs what the vendored ../shared/vendor/kickcat/build.sh needs (cmake, g++,
# nlohmann-json3-dev, libtinyxml2-dev); tools/scripts/system-packages.sh installs
# them when missing and run as root. Incremental: the cmake tree stays in DIR/build.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
kickcat=$(cd "$root/../shared/vendor/kickcat" && pwd)
out=$(mkdir -p "${1:?usage: build.sh DIR [LIB]}" && cd "$1" && pwd)
lib=${2:-}
if [ -z "$lib" ]; then
  (cd "$root" && cargo build -q -p exo-plant-drive --lib)
  lib="${CARGO_TARGET_DIR:-$root/target}/debug/libexo_plant_drive.a"
fi
[ -f "$lib" ] || { echo "plant-drive build: $lib not found" >&2; exit 1; }
# The packages it builds with: installed when missing (as root), or named.
"$root/tools/scripts/system-packages.sh" "plant-drive build"
if [ ! -f "$out/argparse-prefix/.done" ]; then
  cmake -S "$kickcat/argparse" -B "$out/argparse-build" -DCMAKE_INSTALL_PREFIX="$out/argparse-prefix" \
    -DARGPARSE_BUILD_TESTS=OFF -DARGPARSE_BUILD_SAMPLES=OFF >/dev/null
  cmake --install "$out/argparse-build" >/dev/null
  touch "$out/argparse-prefix/.done"
fi
cmake -S "$here" -B "$out/build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$out/argparse-prefix" \
  -DKICKCAT_SRC="$kickcat/src" -DEXO_PLANT_DRIVE_LIB="$lib" >/dev/null
cmake --build "$out/build" -j"$(nproc)" --target exo_plant_drive >/dev/null
cp "$out/build/exo_plant_drive" "$out/"
mkdir -p "$out/slave_configs"
cp "$kickcat/src/simulation/slave_configs/ecat402-drive.xml" "$here/slave_configs/exo-drive.json" "$out/slave_configs/"
echo "$out/exo_plant_drive"
