#!/usr/bin/env bash
# Build the paper's 8-D map (final x, y + six duty factors, CVT) in the background-safe way:
# the same command starts the build and, when its checkpoint exists, resumes it (after a
# kill, a reboot, or on another machine where the checkpoint and its .journal folder were
# copied to $MAPBUILD_DIR). Progress goes to $MAPBUILD_DIR/build.log.
#
#   scripts/build_map8d.sh                       # 1 local worker, ~/.cache/sela_ros/mapbuild
#   WORKERS=16 MAPBUILD_DIR=~/mapbuild scripts/build_map8d.sh
#   DASK=tcp://scheduler:8786 scripts/build_map8d.sh
#   setsid nohup nice -n 10 scripts/build_map8d.sh >/dev/null 2>&1 </dev/null &  # survives a logout
#
# The run's settings (seed, batch size, physics) live in the checkpoint once it exists:
# changing SEED then has no effect; EVALUATIONS may grow; a larger CELLS goes on in a finer
# CVT with every elite found so far carried into it (--regrid), a smaller one is refused.
set -euo pipefail
cd "$(dirname "$0")/.."
MAPBUILD_DIR=${MAPBUILD_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/sela_ros/mapbuild}
EVALUATIONS=${EVALUATIONS:-200000}
CELLS=${CELLS:-60000}
SEED=${SEED:-1}
WORKERS=${WORKERS:-1}
PY=${PY:-.venv/bin/python}
mkdir -p "$MAPBUILD_DIR"
checkpoint="$MAPBUILD_DIR/map8d.checkpoint.pkl"
args=(--descriptor 8d --cells "$CELLS" --evaluations "$EVALUATIONS" --batch-size 200
      --seed "$SEED" --workers "$WORKERS" --checkpoint-every 5 --checkpoint "$checkpoint"
      --out "$MAPBUILD_DIR/map8d.npz")
[[ -n "${DASK:-}" ]] && args+=(--dask-scheduler "$DASK")
[[ -f "$checkpoint" ]] && args+=(--resume --regrid "$CELLS")
echo "$(date -u +%FT%TZ) build_map8d: $PY -m sela_ros.tools.build_archive ${args[*]}" \
    >> "$MAPBUILD_DIR/build.log"
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
# One build per checkpoint: a second one would interleave batches in the same journal.
exec flock --nonblock --conflict-exit-code 3 "$MAPBUILD_DIR/build.lock" \
    "$PY" -m sela_ros.tools.build_archive "${args[@]}" >> "$MAPBUILD_DIR/build.log" 2>&1
