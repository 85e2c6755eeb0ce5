#!/usr/bin/env bash
# The GPU-machine checks of issue #32, as one script: build the core, then the world's thread scaling,
# batched SARL scoring on CUDA and training at RGL's replay ratio with the network on CUDA.
# Run from the repository root on a machine with 16 cores and one NVIDIA GPU; logs go to $OUT (or ./gpu_out).
# Needs torch with CUDA, nanobind, cmake and ninja; gymnasium may come as wheels in .whl/.
set -uo pipefail
OUT=${OUT:-gpu_out}; mkdir -p "$OUT"
if ls .whl/*.whl >/dev/null 2>&1; then
  python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl
  export PYTHONPATH=/tmp/site
fi
export PYTHONPATH=src${PYTHONPATH:+:$PYTHONPATH} PYTHONUNBUFFERED=1
{ nproc; lscpu | grep -E 'Model name|Flags' | cut -c1-300; nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv;
  python3 -c 'import torch; print("torch", torch.__version__, torch.cuda.get_device_name(0))'; } 2>&1 | tee "$OUT/machine.txt"
cmake -S . -B build/gpu -G Ninja -DCMAKE_BUILD_TYPE=Release -DPython_EXECUTABLE="$(command -v python3)" >/dev/null \
  && cmake --build build/gpu >/dev/null && cp build/gpu/_core*.so src/socialnav/ || { echo "build failed"; exit 1; }
run() { local name=$1; shift; echo "== $name: $*"; timeout "${LIMIT:-240}" "$@" 2>&1 | tee "$OUT/$name.txt" | tail -n "${TAILN:-4}"; }
STAGES=${STAGES:-"world policy train"}
for stage in $STAGES; do case $stage in
  world)
    run bench_world_b4096 python3 benchmarks/bench_world.py --batch 4096 --seconds 2 --scaling-threads 1 2 4 8 16 --scaling-repeats 2 --scaling-seconds 2
    run bench_world_b16384 python3 benchmarks/bench_world.py --batch 16384 --seconds 2 --scaling-threads 1 2 4 8 16 --scaling-repeats 2 --scaling-seconds 2 ;;
  policy)
    run bench_policy_cuda python3 benchmarks/bench_policy.py --device cuda --threads 16 --batches 1024 4096 16384
    run bench_policy_cpu16 python3 benchmarks/bench_policy.py --threads 16 --batches 1024 4096 ;;
  train)
    run bench_train_step_cuda python3 benchmarks/bench_train.py --host-overhead-only --device cuda
    LIMIT=300 run bench_train_ratio100_cuda python3 benchmarks/bench_train.py --device cuda --gradient-steps-per-episode 100 \
      --rl-episodes 100 --il-episodes 200 --il-epochs 10 --validate-every 100 --max-minutes 5 ;;
  breakdown)
    lscpu 2>&1 | tee "$OUT/lscpu.txt" | grep -E 'Thread|Core|Socket|NUMA node|L2|L3|Model name'
    run world_breakdown_b4096 python3 benchmarks/gpu/world_breakdown.py --batch 4096 --threads 1 2 4 8 16
    run world_breakdown_b16384 python3 benchmarks/gpu/world_breakdown.py --batch 16384 --threads 1 8 16 ;;
  graphtest)
    run test_fused_step_cuda python3 -m pytest -q -p no:cacheprovider tests/train/test_fused_step.py -k cuda_graph ;;
  trainstep_compiled)
    run bench_train_step_cuda_compiled python3 benchmarks/bench_train.py --host-overhead-only --device cuda --compile ;;
  train_compiled)
    LIMIT=300 run bench_train_ratio100_cuda_compiled python3 benchmarks/bench_train.py --device cuda --compile \
      --gradient-steps-per-episode 100 --rl-episodes 600 --il-episodes 200 --il-epochs 10 --validate-every 200 \
      --max-minutes 4 --skip-step-timing ;;
  malloc)  # the same with glibc keeping freed memory (no trim, no mmap for large arrays): A/B in one run
    run world_breakdown_b16384_default python3 benchmarks/gpu/world_breakdown.py --batch 16384 --threads 1 16
    MALLOC_MMAP_THRESHOLD_=1073741824 MALLOC_TRIM_THRESHOLD_=2147483648 MALLOC_TOP_PAD_=67108864 \
      run world_breakdown_b16384_keep python3 benchmarks/gpu/world_breakdown.py --batch 16384 --threads 1 16
    MALLOC_MMAP_THRESHOLD_=1073741824 MALLOC_TRIM_THRESHOLD_=2147483648 MALLOC_TOP_PAD_=67108864 \
      run bench_world_b4096_keep python3 benchmarks/bench_world.py --batch 4096 --seconds 1 --scaling-threads 1 16 --scaling-repeats 2 --scaling-seconds 2
    MALLOC_MMAP_THRESHOLD_=1073741824 MALLOC_TRIM_THRESHOLD_=2147483648 MALLOC_TOP_PAD_=67108864 \
      run bench_world_b16384_keep python3 benchmarks/bench_world.py --batch 16384 --seconds 1 --scaling-threads 1 16 --scaling-repeats 2 --scaling-seconds 2 ;;
  avx512_2core)  # issue #32's Intel figure: the native scorer on 2 cores of the Xeon, AVX-512 vs AVX2 kernel
    for kernel in avx512 avx2; do
      LIMIT=90 run bench_policy_2core_$kernel taskset -c 0,1 python3 benchmarks/bench_policy.py --threads 2 \
        --batches 1024 --kernel $kernel
    done ;;
  train_walls)  # issue #28: RGL among walls, the default schedule, network on CUDA (compiled), resumable output
    start=$SECONDS
    timeout "${TRAIN_LIMIT:-420}" python3 -m socialnav.cli train --policy rgl --preset francis2023 --seed 0 \
      --device cuda --compile --out "$OUT/francis2023-rgl-s0" --no-progress > "$OUT/train_walls.txt" 2>&1
    rc=$?; echo "train_walls (compiled): rc $rc after $((SECONDS - start)) s"; tail -n 15 "$OUT/train_walls.txt"
    left=$(( ${TRAIN_LIMIT:-420} - (SECONDS - start) ))
    if [ "$rc" != 0 ] && [ "$rc" != 124 ] && [ "$left" -gt 30 ]; then  # compile failed: resume eagerly
      timeout "$left" python3 -m socialnav.cli train --policy rgl --preset francis2023 --seed 0 --device cuda \
        --out "$OUT/francis2023-rgl-s0" --no-progress > "$OUT/train_walls_eager.txt" 2>&1
      echo "train_walls (eager): rc $?"; tail -n 15 "$OUT/train_walls_eager.txt"
    fi
    rm -f "$OUT/francis2023-rgl-s0/il_demos.npz" ;;
esac; done
