#!/usr/bin/env bash
# The sensor end to end on simulated grasps (`make demo`):
# a rig's files -> sync -> frames -> crop -> augment -> a force model and a material classifier,
# scored on held-out grasps simulated with another seed. Writes everything into $1 (demo-out/).
set -euo pipefail
out=${1:-demo-out}
mkdir -p "$out"
step() { printf '\n== %s\n' "$*" >&2; }

step "simulate the rig: bolts of 8, 12 and 16 mm (thesis ch. 4), training and held-out grasps"
neurotac simulate --preset ch4 --seed 1 --out "$out/rig-train"
neurotac simulate --preset ch4 --seed 2 --trials 9 --out "$out/rig-test"

step "sync each grasp at its LED-off spike, frame at 10 ms, crop 115x115 around the contact"
for split in train test; do
  neurotac sync --manifest "$out/rig-$split/manifest.csv" \
    | neurotac frame --window 10ms --pad-to 41 \
    | neurotac crop --size 115x115 --center 120,90 -o "$out/frames-$split.arrows"
done
neurotac info "$out/frames-test.arrows" | head -12

step "augment the training grasps: temporal event shifting, the thesis's best setting"
neurotac augment --tes -2 0.5 --seed 1 < "$out/frames-train.arrows" > "$out/frames-train-aug.arrows"

step "train our force model (validation: a share of grasps per bolt size)"
neurotac train --model deform-gru --seed 1 --val-fraction 0.15 --epochs 400 --plot "$out/force-training.png" \
  -o "$out/force.model" < "$out/frames-train-aug.arrows"

step "force on the held-out grasps"
neurotac eval --model "$out/force.model" --metrics "$out/force-metrics.parquet" \
  --plot "$out/force-traces.png" < "$out/frames-test.arrows" > "$out/force-predictions.arrows"

step "materials (thesis ch. 3): foam, rubber, silicone, steel, from accumulated ON/OFF counts"
neurotac simulate --preset ch3 --seed 1 --synced \
  | neurotac frame --window 7ms --accumulate | neurotac crop --pool all -o "$out/materials-train.arrows"
neurotac simulate --preset ch3 --seed 2 --trials 16 --synced \
  | neurotac frame --window 7ms --accumulate | neurotac crop --pool all -o "$out/materials-test.arrows"
neurotac train --model material-curves --seed 1 --epochs 300 -o "$out/material.model" < "$out/materials-train.arrows"
neurotac eval --model "$out/material.model" --metrics "$out/material-metrics.parquet" \
  --plot "$out/confusion.png" < "$out/materials-test.arrows" > "$out/material-predictions.arrows"
neurotac classify --model "$out/material.model" < "$out/materials-test.arrows" | neurotac info - | head -4

step "done: plots in $out/ (force-traces.png, force-training.png, confusion.png)"
