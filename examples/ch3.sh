#!/usr/bin/env bash
# Thesis chapter 3 on simulated grasps: force from accumulated ON/OFF events (TDNN k x n grid and GP,
# leave-one-out, Tables 3.1-3.2, Figs 3.9-3.10), materials from the same events (DNN k x n grid,
# Tables 3.3-3.4, Fig. 3.13) and the force-sensor-only classifier.
#   MODE=full|quick|tiny bash examples/ch3.sh        (see lib.sh for OUT, RESULTS, SEED, NEUROTAC_*)
source "$(dirname "$0")/lib.sh"
DIR=$OUT/ch3
mkdir -p "$DIR"
START=$SECONDS

if [[ $MODE == full ]]; then
  TRIALS=()                                  # the preset's 48 grasps: foam 11, rubber 9, silicone 14, steel 14
  TDNN_LAYERS=(1 2 3 4 5); TDNN_UNITS=(5 10 15 20 25 30 35 40)
  DNN_LAYERS=(1 2 3 4 5 6); DNN_UNITS=(5 10 15 20 25 30)
  FIT=()                                     # the models' defaults: early stopping after 20 epochs
  GP_FIT=()                                  # 1500 frames, 3 restarts
  CV=loo
elif [[ $MODE == tiny ]]; then
  TRIALS=(--trials 8)
  TDNN_LAYERS=(1); TDNN_UNITS=(5)
  DNN_LAYERS=(1); DNN_UNITS=(5)
  FIT=(--epochs 2 --patience 1)
  GP_FIT=(--max-points 50 --restarts 0)
  CV=kfold:2
else
  TRIALS=(--trials 8)                        # two grasps per material
  TDNN_LAYERS=(1 4); TDNN_UNITS=(5 40)
  DNN_LAYERS=(1 2); DNN_UNITS=(10 30)
  FIT=(--epochs 30 --patience 5)
  GP_FIT=(--max-points 200 --restarts 1)
  CV=loo
fi

# Grasps -> synced trials -> 7 ms frames (144 per grasp, padded to the longest) -> one pixel per
# channel: the accumulated ON and OFF counts of thesis 3.4 (the models accumulate over time).
if [[ ! -s $DIR/frames.parquet ]]; then
  say "simulating the ch3 preset (seed $SEED)"
  neurotac simulate --preset ch3 --seed "$SEED" "${TRIALS[@]}" --out "$DIR/sim"
  neurotac sync --manifest "$DIR/sim/manifest.csv" \
    | neurotac frame --window 7ms --pad-to longest \
    | neurotac crop --pool all -o "$DIR/frames.parquet"
fi
FRAMES=$DIR/frames.parquet

# Force: the TDNN grid, every point a leave-one-out study (all trainings of the grid one study);
# validation trials drawn per material in every fold. Its metrics hold both tables of the thesis:
# each fold's validation error at the restored best epoch (val_mse, Table 3.1) and the error on
# the left-out grasp (mse, Table 3.2).
grid tdnn --model-spec tdnn --grid "layers=$(join "${TDNN_LAYERS[@]}")" --grid "units=$(join "${TDNN_UNITS[@]}")" \
  "${FIT[@]}" --cv "$CV" --val-per material "$FRAMES"
# The figure and the TDNN row beside the GP show the thesis's chosen network (Table 3.1: k=4, n=40).
figure "$FIGURES/ch3-tdnn.png" --cv "$CV" --model-spec tdnn --layers 4 --units 40 \
  --val-per material "${FIT[@]}" "$FRAMES"
study gp --cv "$CV" --model-spec gp --val-per material "${GP_FIT[@]}" --plot "$FIGURES/ch3-gp.png" "$FRAMES"

# Materials: the DNN grid on the accumulation curves, and the same network on the force log alone.
grid material-dnn --model-spec material-dnn --grid "layers=$(join "${DNN_LAYERS[@]}")" \
  --grid "units=$(join "${DNN_UNITS[@]}")" "${FIT[@]}" --cv "$CV" --val-per material "$FRAMES"
figure "$FIGURES/ch3-confusion.png" --cv "$CV" --model-spec material-dnn --layers 2 --units 30 \
  --val-per material "${FIT[@]}" "$FRAMES"
study material-force --cv "$CV" --model-spec material-force --val-per material "${FIT[@]}" "$FRAMES"

publish ch3 "Run: \`MODE=$MODE\`, \`simulate --preset ch3 --seed $SEED ${TRIALS[*]}\`, $CV cross-validation, $((SECONDS - START)) s on $(machine) (this invocation; studies finished before are reused)."
