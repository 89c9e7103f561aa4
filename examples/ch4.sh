#!/usr/bin/env bash
# Thesis chapter 4 on simulated grasps: force from spatio-temporal frames of bolts of three sizes.
# The validation error of LSTM, CNNLSTM and ConvLSTM against their number of layers (Fig. 4.4(a)),
# TDNN, LSTM, CNNLSTM and ConvLSTM with leave-one-out (Table 4.3), MSE per phase (Table 4.4), DTW and
# Bhattacharyya distances per phase (Table 4.5), and ConvLSTM on an object size it never saw (4.6).
#   MODE=full|quick bash examples/ch4.sh        (see lib.sh for OUT, RESULTS, SEED, NEUROTAC_*)
source "$(dirname "$0")/lib.sh"
DIR=$OUT/ch4
mkdir -p "$DIR"
START=$SECONDS

if [[ $MODE == full ]]; then
  TRIALS=()                    # the preset's 35 grasps: bolts of 8 mm (12), 12 mm (12), 16 mm (11)
  SIZE=115x115; POOL=()        # 115x115 frames, as the thesis
  FIT=()                       # the models' defaults (thesis architectures, early stopping after 20 epochs)
  SWEEP=(1 2 3 4 5 6 7)        # hidden layers of Fig. 4.4(a)
  CV=loo
  SEEDS=10                     # trainings per model on the held-out size
  PROTOCOL="Protocol: the thesis's (all 35 grasps, 115x115 frames, leave-one-out, its architectures, early stopping after 20 epochs); the held-out size over $SEEDS seeds."
elif [[ $MODE == standard ]]; then
  TRIALS=()
  # A 115x115 ConvLSTM fold costs 442 CPU s (35 folds x 7 depths: 30 CPU h); pooled 4x4 to 29x29
  # the frames keep the contact's layout at about 1/16 of the pixels.
  SIZE=116x116; POOL=(--pool 4x4)
  FIT=()
  SWEEP=(1 2 4)                # of the thesis's 1-7
  # A ConvLSTM fold at 29x29 still costs over 185 CPU s: 5 folds (7 grasps each) instead of 35,
  # shared by the sweep and the table (the sweep's depth-4 point is the table's ConvLSTM).
  CV=kfold:5
  SEEDS=5
  PROTOCOL="Protocol: standard (\`make reproduce\`): all 35 grasps, the thesis's architectures and early stopping; 5 folds of 7 grasps instead of leave-one-out; frames pooled 4x4 to 29x29 (thesis 115x115); the depth sweep at 1, 2 and 4 layers (thesis 1-7); the held-out size over $SEEDS seeds."
else
  TRIALS=(--trials 6)          # two grasps per bolt
  SIZE=115x115; POOL=(--pool 5x5)  # 23x23 frames
  FIT=(--epochs 4 --patience 2)
  SWEEP=(1 2 4)
  CV=loo
  SEEDS=2
  PROTOCOL="Protocol: 6 grasps, 23x23 frames, at most 4 epochs (patience 2), leave-one-out, $SEEDS seeds on the held-out size."
fi
# SWEEP_LAYERS replaces the mode's depths ("" runs no sweep): the full sweep is 30 of its 43 CPU hours.
if [[ -v SWEEP_LAYERS ]]; then
  read -ra SWEEP <<< "$SWEEP_LAYERS"
  PROTOCOL="$PROTOCOL Depth sweep: ${SWEEP_LAYERS:-not run} (\`SWEEP_LAYERS\`)."
fi
# The thesis's chosen number of layers (Fig. 4.4(a)), the models' defaults; given explicitly so the
# leave-one-out studies below share their trainings with the sweep's point of the same depth.
declare -A LAYERS=([tdnn]=4 [lstm]=6 [cnnlstm]=4 [convlstm]=4 [deform-gru]=1)

# Grasps -> synced trials -> 10 ms frames padded to the longest grasp (41) -> SIZE around the contact.
if [[ ! -s $DIR/frames.parquet ]]; then
  say "simulating the ch4 preset (seed $SEED)"
  neurotac simulate --preset ch4 --seed "$SEED" "${TRIALS[@]}" --out "$DIR/sim"
  neurotac sync --manifest "$DIR/sim/manifest.csv" \
    | neurotac frame --window 10ms --pad-to longest \
    | neurotac crop --size "$SIZE" --center auto "${POOL[@]}" -o "$DIR/frames.parquet"
fi
FRAMES=$DIR/frames.parquet

# Leave-one-out, one validation grasp drawn per bolt size in every fold, scored on non-zero force
# (thesis 4.6). The sweep first: every depth of every recurrent model, the mean validation error
# over folds choosing the depth (Fig. 4.4(a)).
for model in convlstm lstm cnnlstm; do
  ((${#SWEEP[@]})) || break
  grid "sweep-$model" --model-spec "$model" --grid "layers=$(join "${SWEEP[@]}")" "${FIT[@]}" \
    --cv "$CV" --val-per object --nonzero "$FRAMES"
done
# Then each model at the thesis's chosen depth (Table 4.3-4.5), and ours.
for model in tdnn lstm cnnlstm convlstm deform-gru; do
  plot=()
  [[ $model == convlstm ]] && plot=(--plot "$FIGURES/ch4-convlstm.png")
  study "$model" --cv "$CV" --model-spec "$model" --layers "${LAYERS[$model]}" --val-per object --nonzero \
    "${FIT[@]}" "${plot[@]}" "$FRAMES"
done

# The held-out size: every model trained on the 8 and 16 mm bolts, tested on every 12 mm grasp, over
# seeds (the thesis: ConvLSTM only).
for model in convlstm tdnn lstm cnnlstm deform-gru; do
  study "heldout-$model" --cv group:object=bolt12 --model-spec "$model" --layers "${LAYERS[$model]}" --val-per object \
    --nonzero --repeats "$SEEDS" "${FIT[@]}" "$FRAMES"
done

publish ch4 "Run: \`MODE=$MODE\`, \`simulate --preset ch4 --seed $SEED ${TRIALS[*]}\`, crop $SIZE ${POOL[*]}, $((SECONDS - START)) s on $(machine) (this invocation; studies finished before are reused)." "$PROTOCOL"
