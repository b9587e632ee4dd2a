#!/usr/bin/env bash
# The scan in another orientation (issue 18): a free object's registration must not depend on the
# frame the scan comes in. The small free case of make_free_demo_case.py (the demo capsule with
# landmarks and ICP markers) is registered as given and with its target side (landmark targets,
# ICP markers, truth surface) rotated by 90° and by 180° about the oblique axis (1, 2, 3) through
# the origin, by scripts/register_rotated.py; each rotated result, rotated back, must equal the
# unrotated one to 1e-4 of the template's diagonal. Seconds per run. The same script runs the
# shared vertebrae (docs/registration.md).
#
#   register_rotated_test.sh SINEW_REGISTER
# Exit status: 0 agreed, 1 differed or a run failed.
set -euo pipefail

tool=$(readlink -f "${1:?usage: register_rotated_test.sh SINEW_REGISTER}")
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/sinew_rotated.XXXXXX")
[[ -n ${ROTATED_KEEP:-} ]] || trap 'rm -rf "$work"' EXIT

"$tool" --make-demo-case "$work/demo" >/dev/null
python3 "$here/make_free_demo_case.py" "$work/demo"
python3 "$here/../../scripts/register_rotated.py" "$tool" "$work/demo/free_case.json" \
  "$work/demo/truth_surface.obj" "$work/runs" --angles 90 180 --tolerance 1e-9
