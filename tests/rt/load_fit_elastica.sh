#!/usr/bin/env bash
# The contact-load fit against the shared renderer's exact elastica (tests/rt/test_load_fit_elastica.cpp):
# renders three pads with ../shared/tools/whisker_pad/render.py (still face seed 1, crowded seed 2,
# moving face seed 2: 145 contact whisker-frames) and runs the test on their truth.json files.
# Exit 77 (skipped) without ../shared or the renderer's Python packages.
#
#   load_fit_elastica.sh TEST_BINARY SHARED_DIR
set -euo pipefail
test_binary=$(readlink -f "${1:?usage: load_fit_elastica.sh TEST_BINARY SHARED_DIR}")
renderer=${2:?usage: load_fit_elastica.sh TEST_BINARY SHARED_DIR}/tools/whisker_pad/render.py
if [[ ! -f $renderer ]]; then
  echo "load_fit_elastica: ../shared/tools/whisker_pad is absent: skipped"
  exit 77
fi
if ! /usr/bin/python3 -c 'import numpy, scipy, cv2' 2>/dev/null; then
  echo "load_fit_elastica: the renderer needs python3-numpy, -scipy and -opencv: skipped"
  exit 77
fi
work=$(mktemp -d /tmp/sinew_load_fit_elastica.XXXXXX)
trap 'rm -rf "$work"' EXIT
truth=""
for c in still_face:1 crowded:2 moving_face:2; do
  out="$work/${c%%:*}_s${c##*:}"
  /usr/bin/python3 "$renderer" "$out" --case "${c%%:*}" --seed "${c##*:}" >/dev/null
  truth+="${truth:+:}$out/truth.json"
done
SINEW_ELASTICA_TRUTH=$truth "$test_binary"
