#!/usr/bin/env bash
# Installs the build into a scratch prefix, builds tests/install/project (an outside program that
# finds the package with find_package(Sinew) and links Sinew::rt, and Sinew::offline when built)
# against it, and runs it.
#   test_install.sh BUILD_DIR SOURCE_DIR WORK_DIR
set -euo pipefail
build=$1 src=$2 work=$3
rm -rf "$work" && mkdir -p "$work"
cmake --install "$build" --prefix "$work/prefix" >/dev/null
cmake -S "$src/tests/install/project" -B "$work/build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$work/prefix" >/dev/null
cmake --build "$work/build" >/dev/null
"$work/build/track_rendered_whisker"
if [ -x "$work/build/register_box" ]; then
  "$work/build/register_box" "$work/box"
fi
