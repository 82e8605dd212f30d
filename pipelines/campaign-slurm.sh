#!/usr/bin/env bash
# A campaign split over a Slurm job array, then merged: N tasks each run one shard
# (`rbprops campaign DIR --shard K/N -o SHARDS/K`), and one job after them merges the
# shards into OUT (summary.csv and runs/, byte for byte what one machine writes), then
# the report.
#
#   pipelines/campaign-slurm.sh DIR OUT [N]        # submits N array tasks (default 16) and the merge
#
# Item i of the campaign (0-based, in the summary's order) runs in task K = (i mod N) + 1,
# so every task lists the same items and picks its share alone. Every task must see DIR
# under the same path (it appears in the items' messages) and the same campaign file;
# the merge refuses shards of different campaigns or options, and names a missing one.
# A task whose items failed still writes its shard (its rows say why) and exits 1; the
# merge runs after every task (afterany), writes the table and exits 1 the same way.
#
# Variables: BIN (directory of the rbprops binary, default target/release), CPUS (cores per
# task, default 2), TIME (per task, default 01:00:00), RUNS=0 to skip the items' runs and
# figures (summary only), SBATCH_ARGS (e.g. "--partition=short --account=lab").
# The same with GNU parallel on a few hosts (shared file system), from the repository root:
#   parallel -S host1,host2 --workdir . 'target/release/rbprops campaign DIR --shard {}/8 -o OUT/shards/{} --runs OUT/shards/{}/runs' ::: $(seq 8)
#   target/release/rbprops campaign merge OUT/shards/* -o OUT/merged && target/release/rbprops report OUT/merged -o OUT/report.html
set -euo pipefail
DIR=${1:?usage: campaign-slurm.sh DIR OUT [N]}
OUT=${2:?usage: campaign-slurm.sh DIR OUT [N]}
N=${3:-16}
BIN=$(realpath "${BIN:-target/release}")
CPUS=${CPUS:-2}
TIME=${TIME:-01:00:00}
RUNS=${RUNS:-1}
mkdir -p "$OUT/shards" "$OUT/logs"

shard_cmd='K=$SLURM_ARRAY_TASK_ID; "'"$BIN"'/rbprops" campaign "'"$DIR"'" --shard $K/'"$N"' -o "'"$OUT"'/shards/$K"'
if [ "$RUNS" = 1 ]; then
  shard_cmd+=' --runs "'"$OUT"'/shards/$K/runs"'
fi

array=$(sbatch --parsable ${SBATCH_ARGS:-} --job-name=rbprops-shard --array=1-"$N" \
  --cpus-per-task="$CPUS" --time="$TIME" --output="$OUT/logs/shard-%a.log" \
  --export=ALL,RAYON_NUM_THREADS="$CPUS" --wrap="$shard_cmd")

merge_cmd='"'"$BIN"'/rbprops" campaign merge "'"$OUT"'"/shards/* -o "'"$OUT"'/merged"; status=$?
"'"$BIN"'/rbprops" report "'"$OUT"'/merged" -o "'"$OUT"'/report.html" --title "campaign '"$DIR"'"
exit $status'
merge=$(sbatch --parsable ${SBATCH_ARGS:-} --job-name=rbprops-merge --dependency=afterany:"$array" \
  --time=00:30:00 --output="$OUT/logs/merge.log" --wrap="$merge_cmd")
echo "submitted: shards $array (1-$N), merge $merge → $OUT/merged, $OUT/report.html" >&2
