# Shared by ch3.sh, ch4.sh, ch5.sh (sourced, not run).
#
# Environment:
#   MODE      standard (the thesis's experiments sized for 2 cores: every grasp, the thesis's splits
#             where affordable, several seeds; `make reproduce`), full (the thesis's protocol to the
#             letter, for a cluster), quick (fewer grasps, smaller grids, few epochs; CI) or tiny
#             (ch3.sh only: one grid point, two epochs; the test suite runs it to check the script works)
#   OUT       output folder (default examples/out, examples/out-full or examples/out-quick); one
#             subfolder per chapter
#   RESULTS   the page the tables go into (standard, full: docs/results.md; quick: $OUT/results.md)
#   FIGURES   where the PNGs go (standard, full: docs/results/; quick: $OUT/figures)
#   SEED      the seed of the simulation and of every study (default 1)
#   SWEEP_LAYERS (ch4.sh) the depths of the layer sweep instead of the mode's ("" for none)
#   METHODS   (ch5.sh) `thesis`: only the shifts the thesis reports (FS-1, TES-2 at 0.5)
#   NEUROTAC_JOBS / NEUROTAC_SCHEDULER / NEUROTAC_CACHE: where the studies run (docs/studies.md);
#     NEUROTAC_DEVICE=cuda trains the force networks on a GPU.
#     The cache defaults to $OUT/cache, so an interrupted run resumes where it stopped; full runs
#     default to NEUROTAC_JOBS=0 (one process per core).
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
MODE=${MODE:-quick}
case $MODE in
  standard) OUT=${OUT:-$HERE/out}; RESULTS=${RESULTS:-$HERE/../docs/results.md}; FIGURES=${FIGURES:-$HERE/../docs/results} ;;
  full) OUT=${OUT:-$HERE/out-full}; RESULTS=${RESULTS:-$HERE/../docs/results.md}; FIGURES=${FIGURES:-$HERE/../docs/results} ;;
  quick|tiny) OUT=${OUT:-$HERE/out-$MODE}; RESULTS=${RESULTS:-$OUT/results.md}; FIGURES=${FIGURES:-$OUT/figures} ;;
  *) echo "MODE must be standard, full, quick or tiny, got $MODE" >&2; exit 2 ;;
esac
# A quick run's figures say little about the sensor: it must never overwrite the published page.
inside() { local path; path=$(realpath -m "$1"); [[ $path == "$2" || $path == "$2"/* ]]; }
if [[ $MODE == quick || $MODE == tiny ]]; then
  for path in "$OUT" "$RESULTS" "$FIGURES" "${NEUROTAC_CACHE:-$OUT}"; do
    if inside "$path" "$(realpath -m "$HERE/../docs")"; then
      echo "$(basename "$0" .sh): error: a quick run cannot write to $path (its reduced figures are not the protocol's; leave OUT, RESULTS and FIGURES under examples/, or run MODE=standard)" >&2
      exit 2
    fi
  done
fi
SEED=${SEED:-1}
PYTHON=${PYTHON:-python}
export NEUROTAC_CACHE=${NEUROTAC_CACHE:-$OUT/cache}
# When this invocation began: a study that takes tasks the cache held from before (an earlier,
# resumed or repeated run) reports fewer seconds than its trainings cost (`once`). Studies of one run
# that share trainings count them once, in the study that ran them.
STARTED_AT=$(date -u +%Y-%m-%dT%H:%M:%SZ)
# Each task trains on one thread (so results do not depend on where it ran): a standard or full run uses every
# core through a process pool unless a Dask scheduler is given. Quick runs stay in-process, where
# starting worker processes would cost more than their few small trainings.
if [[ $MODE != quick && $MODE != tiny && -z ${NEUROTAC_SCHEDULER:-} ]]; then
  export NEUROTAC_JOBS=${NEUROTAC_JOBS:-0}
fi
mkdir -p "$OUT" "$FIGURES"

say() { printf '%s: %s\n' "$(basename "$0" .sh)" "$*" >&2; }

# once VERB NAME ARGS...: `neurotac VERB ARGS --metrics DIR/NAME.metrics.parquet`, unless that file
# exists already (a finished study is not run again; a half-finished one resumes from the cache).
# neurotac writes --metrics files atomically: the file appears only once complete.
once() {
  local verb=$1 name=$2; shift 2
  local metrics="$DIR/$name.metrics.parquet"
  if [[ -s $metrics ]]; then
    say "$name: done before, kept ($metrics)"
    return
  fi
  say "$name: neurotac $verb $*"
  local started=$SECONDS log="$DIR/$name.log"
  # stderr to the terminal and to the log (pipefail keeps neurotac's exit status), stdout dropped
  neurotac "$verb" "$@" --seed "$SEED" --metrics "$metrics" 2>&1 > /dev/null | tee "$log" >&2
  # The study's wall time, kept beside it so a resumed run still reports what the whole chapter cost.
  # Seconds that leave out tasks an earlier run trained are marked "cached" (neurotac says when the
  # oldest task it took from the cache finished).
  local seconds=$((SECONDS - started)) oldest
  oldest=$(sed -n 's/.* tasks from the cache .*, the oldest finished \([0-9TZ:-]*\) .*/\1/p' "$log" | sort | head -n 1)
  if [[ -n $oldest && $oldest < $STARTED_AT ]]; then seconds="$seconds cached"; fi
  echo "$seconds" > "$DIR/$name.seconds"
}

# wall_time: the seconds the chapter's finished studies took, summed over every invocation, and how
# many of those studies took tasks from the cache (their seconds leave those tasks out).
wall_time() {
  local sum cached
  sum=$(cat "$DIR"/*.seconds 2>/dev/null | awk '{s += $1} END {print s + 0}')
  cached=$(cat "$DIR"/*.seconds 2>/dev/null | grep -c cached || true)
  if ((cached)); then
    echo "$sum s on $(machine), summed over the chapter's studies ($cached of them took tasks from the cache of an earlier run, whose time this leaves out)"
  else
    echo "$sum s on $(machine), summed over the chapter's studies"
  fi
}

# study NAME ARGS...: one `neurotac eval` cross-validation; grid NAME ARGS...: one `neurotac study`
# grid (one table, one column per grid parameter).
study() { once eval "$@"; }
grid() { once study "$@"; }

# figure PNG EVAL-ARGS...: `neurotac eval EVAL-ARGS --plot PNG`; its trainings are usually in the
# cache already (the same study ran before), so this only scores and draws.
figure() {
  local png=$1; shift
  # a figure older than the chapter's frames is another run's (a fresh clone's copy): drawn again
  [[ -s $png && $png -nt $DIR/frames.parquet ]] || neurotac eval "$@" --seed "$SEED" --plot "$png" > /dev/null
}

join() { local IFS=,; echo "$*"; }

# publish CHAPTER "how it was run" "protocol": write the chapter's tables into $RESULTS. The protocol
# line (where the run departs from the thesis, its seeds, the chapter's wall time) goes under every
# table.
publish() {
  local run=$2 protocol="$3 Wall time $(wall_time)."
  if [[ $MODE == quick || $MODE == tiny ]]; then
    run="**Reduced run** (\`make reproduce-quick\`): it checks the whole pipeline in minutes; its figures are not the thesis's protocol and say little about the sensor. $run"
    protocol="Reduced run, not the thesis's protocol. $protocol"
  fi
  printf '%s\n' "$run" > "$DIR/run.md"
  "$PYTHON" "$HERE/chapters.py" "$1" "$DIR" "$RESULTS" --figures "$FIGURES" --run "$run" --protocol "$protocol"
}

# the machine's cores, not `nproc`'s count, which OMP_NUM_THREADS lowers
machine() { echo "$(getconf _NPROCESSORS_ONLN) CPUs, $(uname -m)"; }
