#!/usr/bin/env bash
# ---------------------------------------------------------------------------------------
# mufe on a Slurm cluster: hybrid MPI (one rank per task) + rayon threads per rank.
#
# How to run
#   1. Build once on the cluster (login node), with the cluster's OpenMPI and parallel HDF5
#      modules loaded:        module load openmpi hdf5/openmpi    # names vary by site
#                             cargo build --release
#   2. Check the scene and see how its grains split over the ranks you ask for
#      (nodes × ntasks-per-node):
#                             target/release/mufe check jobs/demo/sphere_compression.toml
#                             target/release/mufe partition SCENE.toml --parts 8
#   3. Submit (scene and output directory as arguments, both optional):
#                             sbatch jobs/cluster/slurm_run.sh SCENE.toml out/my_run
#      or override the shape of the job on the command line:
#                             sbatch --nodes=4 --ntasks-per-node=8 --cpus-per-task=4 \
#                                    jobs/cluster/slurm_run.sh SCENE.toml out/big
#   4. Results: OUT/results.h5 (+ results.xdmf); log: slurm-<jobid>.out.
#      Inspect with `h5ls -r OUT/results.h5`.
#
# Longer than the time limit: the job requeues itself. Slurm sends SIGUSR1 to this script
# 5 minutes before the limit (--signal=B:USR1@300); the script passes it on to mpirun,
# which forwards it to every rank; mufe finishes its step, writes a checkpoint into
# OUT/checkpoints/, closes results.h5 and exits; the script then runs
# `scontrol requeue $SLURM_JOB_ID`. When the job starts again (same job id, same
# arguments), it finds OUT/checkpoints/ and continues with `--restart latest` (the newest
# valid checkpoint; results.h5 is continued, the restart recorded in /provenance). The
# rank count may differ between the pieces (the grains are re-partitioned). Between
# signals, a checkpoint is written every MUFE_CHECKPOINT_INTERVAL seconds of wall time
# (default 1800), so a node failure loses at most that much. Stop the cycle with
# `scancel`. The margin must cover one step plus a checkpoint write (see
# docs/BENCHMARKS.md for checkpoint write times).
#
# Layout: each MPI rank owns whole grains and runs --threads $SLURM_CPUS_PER_TASK rayon
# threads. Ranks must NOT be bound to a single core (OpenMPI's default), otherwise all
# threads of a rank share one core: we map ranks by node slot with PE=cpus-per-task, which
# binds each rank to its own set of cores; `--bind-to none` is the simple fallback.
# More ranks than grains is an error (every rank needs at least one grain).
#
# The launch line uses OpenMPI's options. Under MPICH/Intel MPI, or to let Slurm launch,
# replace it with:  srun --cpu-bind=cores "$mufe" run "$scene" --out "$out" --threads "$threads"
#
# Environment overrides: MUFE (path of the binary), MPIEXEC (launcher, default mpirun),
# MUFE_EXTRA_ARGS (e.g. "--max-steps 1000 --set simulation.duration=1e-4"),
# MUFE_CHECKPOINT_INTERVAL (seconds of wall time between checkpoints, default 1800).
# ---------------------------------------------------------------------------------------
#SBATCH --job-name=mufe
#SBATCH --nodes=2
#SBATCH --ntasks-per-node=4
#SBATCH --cpus-per-task=8
#SBATCH --time=04:00:00
#SBATCH --exclusive
#SBATCH --output=slurm-%j.out
#SBATCH --open-mode=append
#SBATCH --requeue
#SBATCH --signal=B:USR1@300

set -euo pipefail

scene=${1:-jobs/demo/sphere_compression.toml}
out=${2:-out/slurm_${SLURM_JOB_ID:-local}}
mufe=${MUFE:-$PWD/target/release/mufe}
launcher=${MPIEXEC:-mpirun}
threads=${SLURM_CPUS_PER_TASK:-1}
ranks=${SLURM_NTASKS:-1}

if [[ ! -x "$mufe" ]]; then
    echo "slurm_run.sh: $mufe not found: run 'cargo build --release' first (or set MUFE=...)" >&2
    exit 2
fi

# rayon reads RAYON_NUM_THREADS if --threads is not given; set both so every library agrees.
export RAYON_NUM_THREADS=$threads
export OMP_NUM_THREADS=$threads

echo "mufe job ${SLURM_JOB_ID:-?}: $ranks ranks × $threads threads on ${SLURM_JOB_NUM_NODES:-1} node(s)"
echo "scene: $scene   output: $out   start: $(date -Is)"

# Fail fast on a bad scene (one line on stderr, exit 2) before taking up the allocation.
"$mufe" check "$scene" >/dev/null

# A requeued job continues from its newest valid checkpoint.
restart=()
if compgen -G "$out/checkpoints/step_*.h5" >/dev/null; then
    restart=(--restart latest)
    echo "continuing from the latest checkpoint in $out/checkpoints/"
fi
interval=${MUFE_CHECKPOINT_INTERVAL:-1800}

# Near the time limit: ask mufe to checkpoint and stop, then requeue this job.
launcher_pid=
stop_and_requeue() {
    echo "time limit near ($(date -Is)): asking mufe to write a checkpoint and stop"
    if [[ -n "$launcher_pid" ]]; then
        kill -USR1 "$launcher_pid" 2>/dev/null || true
        wait "$launcher_pid" || true
    fi
    if compgen -G "$out/checkpoints/step_*.h5" >/dev/null; then
        echo "requeueing job ${SLURM_JOB_ID:-?}"
        scontrol requeue "${SLURM_JOB_ID:?not running under Slurm}"
    else
        echo "no checkpoint was written: not requeueing" >&2
    fi
    exit 0
}
trap stop_and_requeue USR1

# The launcher runs in the background so that this shell can take the signal while it
# waits (bash runs a trap only between commands).
# shellcheck disable=SC2086  # MUFE_EXTRA_ARGS is split on purpose
"$launcher" -n "$ranks" \
    --map-by "ppr:${SLURM_NTASKS_PER_NODE:-1}:node:PE=$threads" --bind-to core \
    -x RAYON_NUM_THREADS -x OMP_NUM_THREADS \
    "$mufe" run "$scene" --out "$out" --threads "$threads" \
    --set "output.checkpoint_interval=$interval" "${restart[@]}" ${MUFE_EXTRA_ARGS:-} &
launcher_pid=$!
status=0
wait "$launcher_pid" || status=$?
if [[ $status -ne 0 ]]; then
    echo "mufe ended with status $status ($(date -Is))" >&2
    exit "$status"
fi
echo "done: $(date -Is); results in $out/results.h5"
