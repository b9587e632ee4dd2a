#!/usr/bin/env bash
# sinew-synth --scenario whisker-pad + sinew-track --whiskers end to end, scored against the truth
# by scripts/whisker_truth_check.py; or the shared real whisker video, checked by
# scripts/whisker_check.py (an independent ridge measure). Exit 77 (skipped) when the video is absent.
#   whisker_acceptance.sh BIN_DIR SOURCE_DIR WORK_DIR still|moving|slide|real
set -euo pipefail
bin=$1 src=$2 work=$3 case=$4
rm -rf "$work" && mkdir -p "$work"
# Debian's interpreter, which has python3-numpy and python3-opencv (a pyenv or venv python3 first
# on PATH may not).
py=/usr/bin/python3
[ -x "$py" ] || py=python3
case "$case" in
  still|moving)
    motion=none seed=1
    if [ "$case" = moving ]; then motion=translate_rotate seed=2; fi
    "$bin/sinew-synth" --scenario whisker-pad --out "$work/pad" --face-motion "$motion" \
      --seed "$seed" >/dev/null
    # The rest frame: 20, where no whisker touches anything (the pressed whisker touches the pole
    # on frames 0-12 of the still face's sequence).
    "$bin/sinew-track" --input "$work/pad/frames/f_%04d.png" --whiskers --face left \
      --rest-frame 20 --out "$work/results.jsonl"
    # Measured: still face 99.6 % good (ok and within 0.5 px of the true curve), moving face
    # 99.4 % (2026-12-07; 98.5 % before the fainter of a pair was matched second); every whisker found, no swap; follicles (median per whisker) within 0.39 px (still)
    # and 0.50 px (moving).
    # Contact with the pole (still face): every true contact frame reported but for onset/offset
    # timing, none more than a frame away from one, the contact point (the closest approach)
    # 0.58 px (median) along the whisker from the truth's. With the head moving, the pressed
    # whisker's fit drifts near the pole and 26 of 64 contact frames are missed: reported, not
    # required.
    # The contact load (a normal force at the contact point fitted to the whole whisker, against
    # its shape on frame 20): the contact's moment about the follicle 28.4 % off the truth's
    # (median over 55 contact frames; 6 within 5 %), the force 29.3 %, the quasi-static (Pammer)
    # moment from the curvature change 33.5 % (2026-12-07; 24.8, 27.1 and 30.0 % before frame 0's
    # detection changed); required: median 35 %. (Rest frame 20 is the one
    # rest setting where fitting the follicle's angle does not help: docs/tracker.md.)
    good=0.98 base=1.0 contact=(--max-contact-arc-px 1.5 --max-contact-moment-error 0.35)
    if [ "$case" = moving ]; then good=0.97 contact=(); fi
    "$py" "$src/scripts/whisker_truth_check.py" --results "$work/results.jsonl" \
      --truth "$work/pad/truth.jsonl" --require-found --require-good "$good" --max-base-px "$base" \
      "${contact[@]}"
    ;;
  slide)
    # One whisker (base contrast 20 grey levels, σ = 4) whisking against a pole that slides from
    # 60 % of its length to 40 % and back: the contact point moves along the whisker (83 → 55 px
    # of 140) and the load grows to Δκ = 2× the whisker's rest curvature at the follicle.
    "$bin/sinew-synth" --scenario whisker-pad --out "$work/pad" --whiskers 1 --contrast-min 20 \
      --contrast-max 20 --pole-travel 0.2 --seed 1 >/dev/null
    # The rest frame: 30 (contact on frames 5-20, 54-71, 103-121, 154-170).
    "$bin/sinew-track" --input "$work/pad/frames/f_%04d.png" --whiskers --face left \
      --rest-frame 30 --out "$work/results.jsonl"
    # Measured: 100 % good, curve 0.10 px mean, follicle 0.16 px; contact load on the 54 contact
    # frames after the rest frame, against the truth's frictionless (normal) contact force:
    # moment about the follicle 8.7 % off the truth's (median; 17 within 5 %), force 9.8 % (27
    # within 10 %), Pammer 20.3 % (2026-12-07; 8.3, 9.0 and 20.2 % before frame 0's detection
    # changed). Contact frames:
    # none missed, none reported more than a frame from a true one (a whisker within the touch
    # distance whose load would pull it onto the pole is not pressed: without that rule the
    # offsets nearest the follicle came 2 frames late), the contact point 0.81 px (median) along
    # the whisker from the truth's. The force on the follicle (axial, lateral in the fitted base
    # frame) 9.8 % of the true force off (median; 27 of 54 within 10 %). Required: moment median
    # 15 %, follicle force 20 %, contact timing, point 1.5 px.
    "$py" "$src/scripts/whisker_truth_check.py" --results "$work/results.jsonl" \
      --truth "$work/pad/truth.jsonl" --require-found --require-good 0.98 --max-base-px 1.0 \
      --max-contact-arc-px 1.5 --max-contact-moment-error 0.15 --max-follicle-force-error 0.2
    # Beside it, what the images allow (the Cramer-Rao bound of scripts/whisker_load_bound.py,
    # rest shape, follicle and contact point given): the load's relative sd 1.39 % (median), above
    # 5 % on 8 of the 54 contact frames (the onsets and offsets), above 10 % on 3.
    "$py" "$src/scripts/whisker_load_bound.py" --truth "$work/pad/truth.jsonl" --rest-frame 30 \
      --results "$work/results.jsonl" | tail -n 3
    ;;
  real)
    video="$src/../shared/data/whiskers/test_video_10s.mp4"
    if [ ! -f "$video" ]; then
      echo "skipped: $video is absent"
      exit 77
    fi
    "$bin/sinew-track" --input "$video" --whiskers --face left --out "$work/results.jsonl" \
      --overlay "$work/overlay.mp4"
    # Never on the pole. Detection runs on every frame (--redetect every, the default) and lost
    # whiskers restart on theirs, as do fits that strayed from theirs. On a dark ridge: 98.2 % of
    # the tracked (ok or not converged) whisker-frames, 95.7 % of all; with OpenCV's AVX2 paths
    # off (OPENCV_CPU_DISABLE=AVX2,FMA3, as on an older CPU, where the detection's filters round
    # differently) 98.4 / 95.9 %; the video's mirror images (scripts/whisker_variants.py)
    # 95.4-95.6 % of all (94.7-95.3 before the follicle was oriented by the pad, 2026-12-06), so a
    # bound at the 95 % could flip with rounding. The bounds leave room for other machines
    # (before the follicle's 6-grey-level step: 95.4 % and 90.9 %). Follicle jumps of more than
    # 8 px between tracked frames: 38 (the mirror images 32-38; AVX2 off 36); 41 (38-43) before the
    # orientation by the pad, 57 (51-73) before fits whose follicle passed a neighbour's were
    # discarded (follicle_order_px). With held ridges (2026-12-06): 98.4 / 95.9 %, jumps 37 (AVX2
    # off 98.4 / 95.9 %, 34; the mirror images 95.5-95.9 %, 34-42).
    # A whisker's darkness in the matching and strays placed on their detection (2026-12-06):
    # identities no longer walk (largest median follicle drift 55.1 -> 22.8 px; the dense
    # cluster's ids 3 and 4: 55.1 / 29.3 -> 3.2 / 1.1 px), and the leftmost whisker of the
    # cluster is now held on its own line, 3-5 px from its neighbours, where the first measure
    # cannot see it (on a ridge by it on 205 of 288 tracked frames, by the brightest sides on
    # 279). So the bounds are the 95 % by the brightest sides (99.0 / 97.0 %; AVX2 off
    # 99.0 / 97.1; the mirror images 97.0-97.2 % of all; controls 1.6-1.7 %), the first measure
    # with room (93.2 / 91.3 %, mirror images 91.3-91.4 % of all), follicle jumps (46; 45-46) and
    # the drift. With traces that never leave the face dropped (min_clear_length_px): 99.1 /
    # 97.2 %, mirror images 97.1-97.2 %, first measure 91.5 %, jumps 47-52. With the refit from a
    # detection searching narrowly (associate_narrow_refit): 99.1 / 97.9 %, mirror images
    # 97.9-98.0 %, AVX2 off 97.9 %; first measure 94.3 / 93.1 %; lost 18; jumps 45-46; largest
    # drift 22.9 px. With detection tracing the dense cluster's second whisker to the face
    # (near_follow_px; 6 whiskers on frame 0 instead of 5): 99.0 / 96.8 %, mirror images
    # 96.7-97.0 %, AVX2 off 99.1 / 96.8 %; first measure 85.4 / 83.5 % (it cannot see that whisker:
    # 115 of its 274 tracked frames, 266 by the brightest sides); lost 36-44; jumps 40-47; largest
    # drift 13.7-14.0 px. Follicles out of their first order along the pad (swapped identities):
    # on 2 of 300 frames (the cluster's two, 6 px apart); 205 with 5 whiskers, 221 at 9023819.
    # With the faint whisker beside the longest found too (7 on frame 0; max_gap_towards_face_px)
    # and matched after its brighter neighbour (associate_pair_px; 2026-12-07): 98.5 / 95.7 %,
    # mirror images 95.7-96.0 %, AVX2 off 98.6 / 95.6 %; first measure 85.7 / 83.3 %; lost 56-60;
    # jumps 47-52; largest drift 13.5 px; order broken on 1 frame (2 with AVX2 off). Matched at
    # once with the others, ids 2 and 3 swapped in the whisking bout: order broken on 194 frames.
    "$py" "$src/scripts/whisker_check.py" --video "$video" --results "$work/results.jsonl" \
      --require 0.80 --require-all 0.78 --require-near 0.97 --require-all-near 0.95 \
      --max-jumps 60 --max-drift 25 --max-order-breaks 15
    ;;
  *)
    echo "unknown case $case" >&2
    exit 2
    ;;
esac
