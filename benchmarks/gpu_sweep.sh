#!/bin/bash
# The GPU training sweep of docs/learned-descriptor.md: 8 runs side by side on one GPU (one
# process and one CPU thread each), the "long" runs' epochs sized by a probe so that every run
# ends before DEADLINE seconds (20..60 epochs), then a tar of the models and logs.
#   bash benchmarks/gpu_sweep.sh OUTDIR DEADLINE_S DATA [DEVICE=cuda] [PROBE_STEPS=300]
# DATA: a folder holding middlebury2005_third and middlebury2006_third (the training scenes).
# Run from the repository root; it links the checkout as the stereosim package (no install).
set -u
OUTD=$1; DEADLINE=$2; DATA=$3; DEV=${4:-cuda}; PROBE=${5:-300}
T0=$(date +%s)
export PYTHONUNBUFFERED=1 OMP_NUM_THREADS=1
mkdir -p /tmp/pkg "$OUTD/runs" && ln -sfn "$PWD" /tmp/pkg/stereosim
export PYTHONPATH=/tmp/pkg:${PYTHONPATH:-} NUMBA_CACHE_DIR=/tmp/numba_sweep
LOG=$OUTD/sweep.log
{ date; nproc; nvidia-smi -L 2>&1; python3 -c "import torch, numpy, numba, cv2, sys; print(sys.version.split()[0], torch.__version__, torch.cuda.is_available(), numpy.__version__, numba.__version__, cv2.__version__)"; } >>"$LOG" 2>&1
# name variant extra-args (the long runs get --epochs E; the control keeps 20)
RUNS=(
 "m5w-e20|mixed5x5-wide|--noise-max 8 --blur-max 1.0 --epochs 20"
 "m5w-long|mixed5x5-wide|--noise-max 8 --blur-max 1.0"
 "m5w-long-s64|mixed5x5-wide|--noise-max 8 --blur-max 1.0 --strips 64"
 "m5w-long-n6|mixed5x5-wide|--noise-max 6 --blur-max 1.0"
 "mc4w-long|mccnn4-wide|--noise-max 8 --blur-max 1.0"
 "m7-long|mixed7x7|--noise-max 8 --blur-max 1.0"
 "d5-long|double5x5|--noise-max 8 --blur-max 1.0"
 "m540-long|mixed5x5-40|--noise-max 8 --blur-max 1.0"
)
# probe: every run's settings for PROBE steps, side by side; timed from the moment every run
# has loaded its data and printed its threads line (just before its first step)
for r in "${RUNS[@]}"; do IFS='|' read -r name var extra <<<"$r"
  python3 benchmarks/gpu_train.py train --variant $var $extra --epochs 1 --steps $PROBE --device $DEV --threads 1 --seed 0 --data "$DATA" --checkpoint-every 0 --quiet --out /tmp/probe-$name.npz >>"$OUTD/runs/probe-$name.log" 2>&1 &
done
for i in $(seq 600); do
  n=$(grep -l "^training on" "$OUTD"/runs/probe-*.log 2>/dev/null | wc -l)
  [ "$n" -ge ${#RUNS[@]} ] && break; [ -z "$(jobs -rp)" ] && break; sleep 0.2
done
P0=$(date +%s.%N); wait; P1=$(date +%s.%N)
echo "probe started in $(( $(date +%s)-T0 )) s" >>"$LOG"
PER=$(python3 -c "print(($P1-$P0)/$PROBE)")
NOW=$(date +%s); LEFT=$((DEADLINE-(NOW-T0)))
# the longest run must end inside the time left (85 %, less 15 s for start-up), 20..60 epochs
E=$(python3 -c "e=int((0.85*$LEFT-15)/($PER*1000)); print(max(20,min(60,e)))")
echo "probe: $PROBE steps in $(python3 -c "print($P1-$P0)") s side by side ($PER s/step); $LEFT s left; long runs: $E epochs" >>"$LOG"
for r in "${RUNS[@]}"; do IFS='|' read -r name var extra <<<"$r"
  case "$extra" in *--epochs*) ep="";; *) ep="--epochs $E";; esac
  ( s=$(date +%s); python3 benchmarks/gpu_train.py train --variant $var $extra $ep --device $DEV --threads 1 --seed 0 --data "$DATA" --checkpoint-every 1000 --quiet --out "$OUTD/runs/$name.float.npz" >>"$OUTD/runs/$name.log" 2>&1; echo "$name rc=$? $(( $(date +%s)-s )) s" >>"$LOG" ) &
done
# wait for all, or stop at the deadline (the checkpoints stay)
while [ -n "$(jobs -rp)" ]; do
  [ $(( $(date +%s)-T0 )) -ge $DEADLINE ] && { echo "deadline: stopping $(jobs -rp | wc -l) runs" >>"$LOG"; pkill -INT -f "gpu_train.py train"; sleep 5; break; }
  sleep 2
done
wait
date >>"$LOG"
tar -C "$OUTD" -cf "$OUTD/sweep.tar" runs sweep.log
