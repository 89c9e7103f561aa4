#!/usr/bin/env bash
# Thesis chapter 5 on simulated grasps: augmenting the training data for an object size never seen.
# ConvLSTM (4 layers) trained on the small (12 mm) and large (18 mm) bolts, tested on the medium
# (15 mm) one, without augmentation and with every method of the chapter: rotation, resizing,
# background noise, frame shifting (FS, j = -3..3), temporal event shifting (TES, j x zeta), and
# resize + FS-1 combined independently or hybridised; each trained with several seeds (thesis: 10).
#   MODE=full|quick bash examples/ch5.sh        (see lib.sh for OUT, RESULTS, SEED, NEUROTAC_*)
source "$(dirname "$0")/lib.sh"
DIR=$OUT/ch5
mkdir -p "$DIR/train"
START=$SECONDS
TOOL=("$PYTHON" "$HERE/frames_tool.py")

if [[ $MODE == full ]]; then
  TRIALS=()                                    # 60 grasps: 12, 15, 18 mm bolts x two gripper forces, 10 each
  POOL=2x2                                     # 140x150 -> 70x75, as the thesis
  SEEDS=10
  FIT=()
  SHIFTS=(-3 -2 -1 1 2 3)
  ZETAS=(0.25 0.5 0.75)
  PROTOCOL="Protocol: the thesis's (60 grasps, 70x75 frames, every method, $SEEDS seeds per training set and model)."
elif [[ $MODE == standard ]]; then
  TRIALS=()
  # A 70x75 ConvLSTM training costs 188-500 CPU s (300 of them: 28 CPU h). Pooled 10x10 to 14x15,
  # with the methods the thesis reports figures for (FS-1, TES-2 at 0.5) and both combinations.
  POOL=10x10
  SEEDS=3
  FIT=()
  SHIFTS=(-1)
  ZETAS=()
  PROTOCOL="Protocol: standard (\`make reproduce\`): all 60 grasps; frames pooled 10x10 to 14x15 (thesis 70x75); frame shifting at j=-1 and temporal event shifting at j=-2, zeta=0.5 only (thesis: j=-3..3, zeta 0.25-0.75); $SEEDS seeds per training set and model (thesis 10)."
else
  TRIALS=(--trials 12)                         # two grasps per bolt and gripper force
  POOL=10x10                                   # 14x15 frames
  SEEDS=2
  FIT=(--epochs 4 --patience 2)
  SHIFTS=(-1)
  ZETAS=()
  PROTOCOL="Protocol: 12 grasps, 14x15 frames, at most 4 epochs (patience 2), $SEEDS seeds per training set and model."
fi
# METHODS=thesis keeps, in any mode, the shifts the thesis gives figures for (FS-1, TES-2 at 0.5).
if [[ ${METHODS:-} == thesis && (${#SHIFTS[@]} -ne 1 || ${#ZETAS[@]} -ne 0) ]]; then
  SHIFTS=(-1); ZETAS=()
  PROTOCOL="$PROTOCOL Frame shifting at j=-1 and temporal event shifting at j=-2, zeta=0.5 only (\`METHODS=thesis\`; the thesis's figures are for these)."
fi
SMALL=bolt12 MEDIUM=bolt15 LARGE=bolt18

# Grasps -> 10 ms frames (36 per grasp) -> 140x150 around the contact, pooled; the still scene
# (sensor noise only) framed and cropped to the same pixels for --noise.
if [[ ! -s $DIR/frames.parquet ]]; then
  say "simulating the ch5 preset (seed $SEED)"
  neurotac simulate --preset ch5 --seed "$SEED" "${TRIALS[@]}" --out "$DIR/sim"
  neurotac sync --manifest "$DIR/sim/manifest.csv" \
    | neurotac frame --window 10ms --pad-to longest \
    | neurotac crop --size 140x150 --center auto --pool "$POOL" -o "$DIR/frames.parquet"
fi
FRAMES=$DIR/frames.parquet
if [[ ! -s $DIR/still.parquet ]]; then
  neurotac import "$DIR/sim/still.aedat" \
    | neurotac frame --window 10ms \
    | neurotac crop --box "$("${TOOL[@]}" box "$FRAMES")" --pool "$POOL" -o "$DIR/still.parquet"
fi
for object in $SMALL $LARGE; do
  [[ -s $DIR/$object.parquet ]] || "${TOOL[@]}" select "$FRAMES" "$DIR/$object.parquet" "object=$object"
done

# augmented NAME AUGMENT-OPTIONS...: the frames plus one augmented copy of every grasp.
augmented() {
  local name=$1; shift
  [[ -s $DIR/train/$name.parquet ]] || neurotac augment "$@" --seed "$SEED" "$FRAMES" -o "$DIR/train/$name.parquet"
}
# resized NAME [MORE-OPTIONS...]: copies of the small bolt scaled by 1.25 and of the large by 0.83
# (towards the medium size, thesis 5.5), beside the original frames.
resized() {
  local name=$1; shift
  [[ -s $DIR/train/$name.parquet ]] && return
  neurotac augment --resize 1.25 "$@" --only-augmented --seed "$SEED" "$DIR/$SMALL.parquet" -o "$DIR/$name-small.parquet"
  neurotac augment --resize 0.83 "$@" --only-augmented --seed "$SEED" "$DIR/$LARGE.parquet" -o "$DIR/$name-large.parquet"
  "${TOOL[@]}" concat "$DIR/train/$name.parquet" "$FRAMES" "$DIR/$name-small.parquet" "$DIR/$name-large.parquet"
}

cp -n "$FRAMES" "$DIR/train/none.parquet" 2>/dev/null || true
augmented rot45 --rotate-range 0 45
resized resize
augmented noise --noise "$DIR/still.parquet"
for j in "${SHIFTS[@]}"; do augmented "fs$j" --fs "$j"; done
if ((${#ZETAS[@]})); then
  for j in "${SHIFTS[@]}"; do for zeta in "${ZETAS[@]}"; do augmented "tes${j}_$zeta" --tes "$j" "$zeta"; done; done
else
  augmented tes-2_0.5 --tes -2 0.5
fi
# Resize and FS-1 together: independent copies (one of each per grasp) or one copy with both.
if [[ ! -s $DIR/train/independent.parquet ]]; then
  neurotac augment --fs -1 --only-augmented --seed "$SEED" "$FRAMES" -o "$DIR/fs-1-only.parquet"
  resized resize
  "${TOOL[@]}" concat "$DIR/train/independent.parquet" "$DIR/train/resize.parquet" "$DIR/fs-1-only.parquet"
fi
resized hybrid --fs -1 --combine hybrid

# Every training set: the thesis's ConvLSTM and our deform-gru, $SEEDS seeds each, tested on the
# medium bolt (deform-gru's studies are named deform-gru@SET).
for data in "$DIR"/train/*.parquet; do
  name=$(basename "$data" .parquet)
  study "$name" --cv "group:object=$MEDIUM" --model-spec convlstm --repeats "$SEEDS" --val-per object \
    "${FIT[@]}" "$data"
  study "deform-gru@set=$name" --cv "group:object=$MEDIUM" --model-spec deform-gru --repeats "$SEEDS" --val-per object \
    "${FIT[@]}" "$data"
done

publish ch5 "Run: \`MODE=$MODE\`, \`simulate --preset ch5 --seed $SEED ${TRIALS[*]}\`, crop 140x150 pool $POOL, $SEEDS seeds, $((SECONDS - START)) s on $(machine) (this invocation; studies finished before are reused)." "$PROTOCOL"
