#!/usr/bin/env bash
# sinew-track --whiskers --csv --hdf5 --plots on a short rendered pad, read back with pandas and
# h5py (tests/tools/whisker_table_check.py).
#   whisker_table.sh BIN_DIR SOURCE_DIR WORK_DIR
set -euo pipefail
bin=$1 src=$2 work=$3
rm -rf "$work" && mkdir -p "$work"
py=/usr/bin/python3
[ -x "$py" ] || py=python3
"$bin/sinew-synth" --scenario whisker-pad --out "$work/pad" --whiskers 4 --frames 30 --seed 3 \
  >/dev/null
"$bin/sinew-track" --input "$work/pad/frames/f_%04d.png" --whiskers --face left --quiet \
  --out "$work/w.jsonl" --csv "$work/w.csv" --hdf5 "$work/w.h5" --plots "$work/plots" \
  --mm-per-px 0.05 --base-radius-um 40 --tip-radius-um 2
"$py" "$src/tests/tools/whisker_table_check.py" --csv "$work/w.csv" --hdf5 "$work/w.h5" \
  --jsonl "$work/w.jsonl" --plots "$work/plots"
