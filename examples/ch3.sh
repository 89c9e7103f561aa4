#!/usr/bin/env bash
# Thesis chapter 3 on simulated grasps: force from accumulated ON/OFF events (TDNN k x n grid and GP,
# leave-one-out, Tables 3.1-3.2, Figs 3.9-3.10), materials from the same events (DNN k x n grid,
# Tables 3.3-3.4, Fig. 3.13) and the force-sensor-only classifier.
#   MODE=standard|full|quick|tiny bash examples/ch3.sh        (see lib.sh for OUT, RESULTS, SEED, NEUROTAC_*)
source "$(dirname "$0")/lib.sh"
DIR=$OUT/ch3
mkdir -p "$DIR"
START=$SECONDS

if [[ $MODE == full || $MODE == standard ]]; then
  TRIALS=()                                  # the preset's 48 grasps: foam 11, rubber 9, silicone 14, steel 14
  TDNN_LAYERS=(1 2 3 4 5); TDNN_UNITS=(5 10 15 20 25 30 35 40)
  DNN_LAYERS=(1 2 3 4 5 6); DNN_UNITS=(5 10 15 20 25 30)
  FIT=()                                     # the models' defaults: early stopping after 20 epochs
  GP_FIT=()                                  # 1500 frames, 3 restarts
  CV=loo
  MATERIAL_CV=loo
  SEEDS=10                                   # seeds of the chosen classifiers (one training per fold and seed)
  PROTOCOL="Protocol: the thesis's (all 48 grasps, leave-one-out, its grids, early stopping after 20 epochs); the chosen classifiers over $SEEDS seeds."
  if [[ $MODE == standard ]]; then
    # The GP's 48 folds at 1500 frames and 3 restarts cost 2.4 CPU h: a 500-frame subset and one
    # restart (n^3: about 1/27 of the fit) keeps the leave-one-out; the material grid in 8 folds.
    GP_FIT=(--max-points 500 --restarts 1)
    MATERIAL_CV=kfold:8
    SEEDS=3
    PROTOCOL="Protocol: standard (\`make reproduce\`): all 48 grasps, the thesis's grids and early stopping; leave-one-out for force, the GP on 500 frames with 1 restart (thesis: Bayesian-optimised on all), the material grid in 8 folds instead of leave-one-out, the chosen classifiers over $SEEDS seeds."
  fi
elif [[ $MODE == tiny ]]; then
  # 4 grasps per material in 4 folds: each fold trains on at least 2 grasps of every material before
  # one is drawn for early stopping (a discriminant needs a material of 2 to pool a spread within)
  TRIALS=(--trials 16)
  TDNN_LAYERS=(1); TDNN_UNITS=(5)
  DNN_LAYERS=(1); DNN_UNITS=(5)
  FIT=(--epochs 2 --patience 1)
  GP_FIT=(--max-points 50 --restarts 0)
  CV=kfold:4
  MATERIAL_CV=kfold:4
  SEEDS=1
  PROTOCOL="Protocol: tiny (one grid point, two epochs: a check that the script runs, not a result)."
else
  TRIALS=(--trials 16)                       # four grasps per material, as in the tiny run
  TDNN_LAYERS=(1 4); TDNN_UNITS=(5 40)
  DNN_LAYERS=(1 2); DNN_UNITS=(10 30)
  FIT=(--epochs 30 --patience 5)
  GP_FIT=(--max-points 200 --restarts 1)
  CV=kfold:4
  MATERIAL_CV=kfold:4
  SEEDS=2
  PROTOCOL="Protocol: 16 grasps, 2x2 grids, at most 30 epochs (patience 5), 4 folds, $SEEDS seeds for the chosen classifiers."
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
# Our force model reads the deformation's layout: the same grasps framed around the contact, pooled.
if [[ ! -s $DIR/frames-spatial.parquet ]]; then
  neurotac sync --manifest "$DIR/sim/manifest.csv" \
    | neurotac frame --window 7ms --pad-to longest \
    | neurotac crop --size 116x116 --center auto --pool 4x4 -o "$DIR/frames-spatial.parquet"
fi

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
study deform-gru --cv "$CV" --model-spec deform-gru --val-per material "${FIT[@]}" "$DIR/frames-spatial.parquet"

# Materials: the DNN grid on the accumulation curves, and the same network on the force log alone.
grid material-dnn --model-spec material-dnn --grid "layers=$(join "${DNN_LAYERS[@]}")" \
  --grid "units=$(join "${DNN_UNITS[@]}")" "${FIT[@]}" --cv "$MATERIAL_CV" --val-per material "$FRAMES"
figure "$FIGURES/ch3-confusion.png" --cv "$MATERIAL_CV" --model-spec material-dnn --layers 2 --units 30 \
  --val-per material "${FIT[@]}" "$FRAMES"
# The thesis's chosen DNN, the force-only network and ours, each over several seeds for a ± over seeds.
study material-dnn-k2-n30 --cv "$CV" --model-spec material-dnn --layers 2 --units 30 --val-per material --repeats "$SEEDS" \
  "${FIT[@]}" "$FRAMES"
for model in material-force material-curves material-timing; do
  study "$model" --cv "$CV" --model-spec "$model" --val-per material --repeats "$SEEDS" "${FIT[@]}" "$FRAMES"
done

publish ch3 "Run: \`MODE=$MODE\`, \`simulate --preset ch3 --seed $SEED ${TRIALS[*]}\`, $((SECONDS - START)) s on $(machine) (this invocation; studies finished before are reused)." "$PROTOCOL"
