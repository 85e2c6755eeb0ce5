#!/usr/bin/env bash
# The GPU-machine checks of issue #32, as one script: build the core, then the world's thread scaling,
# batched SARL scoring on CUDA and training at RGL's replay ratio with the network on CUDA.
# Run from the repository root on a machine with 16 cores and one NVIDIA GPU; logs go to $OUT (or ./gpu_out).
# Needs torch with CUDA, nanobind, cmake and ninja; gymnasium may come as wheels in .whl/.
# STAGES picks the stages (default "world policy train"). `STAGES=final` gives issue #32's CPU figures on
# the 16-core host in ~2.5 minutes: world scaling at 1-16 threads (B = 4096 and 16384) with the machine's
# ceiling (16 independent 1-thread worlds), the breakdown at
# B = 4096 (also among walls, 1 and 16 threads), the walls benchmark, and the native SARL scorer at B = 1024 with its AVX-512 and AVX2
# kernels on 1 and 16 threads. Elsewhere it runs with smaller sizes, e.g.
#   STAGES=final FINAL_BATCHES="256 512" FINAL_THREADS="1 2" FINAL_SECONDS=0.3 FINAL_POLICY_BATCH=64 \
#     FINAL_POLICY_THREADS="1 2" OUT=/tmp/final bash benchmarks/gpu/run_checks.sh
set -uo pipefail
OUT=${OUT:-gpu_out}; mkdir -p "$OUT"
if ls .whl/*.whl >/dev/null 2>&1; then
  python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl
  export PYTHONPATH=/tmp/site
fi
export PYTHONPATH=src${PYTHONPATH:+:$PYTHONPATH} PYTHONUNBUFFERED=1
{ nproc; lscpu | grep -E 'Model name|Flags' | cut -c1-300; nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv;
  python3 -c 'import torch; print("torch", torch.__version__, torch.cuda.get_device_name(0))'; } 2>&1 | tee "$OUT/machine.txt"
# The native core of source tree $1, built in $2 and copied into $1/src/socialnav.
build_core() {
  cmake -S "$1" -B "$2" -G Ninja -DCMAKE_BUILD_TYPE=Release -DPython_EXECUTABLE="$(command -v python3)" >/dev/null \
    && cmake --build "$2" >/dev/null && cp "$2"/_core*.so "$1"/src/socialnav/
}
build_core . build/gpu || { echo "build failed"; exit 1; }
run() { local name=$1; shift; echo "== $name: $*"; timeout "${LIMIT:-240}" "$@" 2>&1 | tee "$OUT/$name.txt" | tail -n "${TAILN:-4}"; }
STAGES=${STAGES:-"world policy train"}
# Sizes of the `final` stage (the defaults are the GPU machine's; smaller ones test the stage elsewhere).
FINAL_BATCHES=${FINAL_BATCHES:-"4096 16384"}
FINAL_THREADS=${FINAL_THREADS:-"1 2 4 8 16"}
FINAL_SECONDS=${FINAL_SECONDS:-1}
FINAL_POLICY_BATCH=${FINAL_POLICY_BATCH:-1024}
FINAL_POLICY_THREADS=${FINAL_POLICY_THREADS:-"1 16"}
for stage in $STAGES; do case $stage in
  world)
    run bench_world_b4096 python3 benchmarks/bench_world.py --batch 4096 --seconds 2 --scaling-threads 1 2 4 8 16 --scaling-repeats 2 --scaling-seconds 2 --scaling-ceiling
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
  final)  # issue #32's 16-core figures in one stage of ~150 s: world scaling, its breakdown, walls, scorer kernels
    start=$SECONDS
    for b in $FINAL_BATCHES; do
      # shellcheck disable=SC2086  # the thread lists are word lists
      LIMIT=90 run "final_bench_world_b$b" python3 benchmarks/bench_world.py --batch "$b" --seconds "$FINAL_SECONDS" \
        --scaling-threads $FINAL_THREADS --scaling-repeats 2 --scaling-seconds "$FINAL_SECONDS" --scaling-ceiling
    done
    first_batch=${FINAL_BATCHES%% *}
    # shellcheck disable=SC2086
    LIMIT=40 run "final_world_breakdown_b$first_batch" python3 benchmarks/gpu/world_breakdown.py --batch "$first_batch" \
      --threads $FINAL_THREADS --seconds "$FINAL_SECONDS"
    # shellcheck disable=SC2086
    LIMIT=40 run "final_world_breakdown_spokes_b$first_batch" python3 benchmarks/gpu/world_breakdown.py \
      --batch "$first_batch" --threads ${FINAL_THREADS%% *} ${FINAL_THREADS##* } --seconds "$FINAL_SECONDS" --map spokes
    LIMIT=40 run final_bench_world_obstacles python3 benchmarks/bench_world.py --obstacles --batch "$first_batch" \
      --seconds "$FINAL_SECONDS" --repeats 2
    for kernel in avx512 avx2; do
      for t in $FINAL_POLICY_THREADS; do
        SOCIALNAV_SCORER_KERNEL=$kernel LIMIT=40 run "final_bench_policy_${kernel}_t$t" python3 benchmarks/bench_policy.py \
          --batches "$FINAL_POLICY_BATCH" --threads "$t" --min-time 0.5 --scorer native --skip-rgl
      done
    done
    echo "== final stage: $((SECONDS - start)) s" | tee "$OUT/final_stage_seconds.txt" ;;
  graphtest)
    run test_fused_step_cuda python3 -m pytest -q -p no:cacheprovider tests/train/test_fused_step.py -k cuda_graph ;;
  cudatests)  # every test that runs only where CUDA is available (they skip elsewhere)
    LIMIT=300 TAILN=12 run test_cuda python3 -m pytest -q -p no:cacheprovider -rs -k cuda tests/train tests/learned \
      tests/evaluate/test_hardening.py tests/sweep/test_sweep.py ;;
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
  pool_ab)  # issue #32: this tree's thread pool against the one in $BASE_POOL (its thread_pool.cpp/.hpp), same run.
    # Prepare the folder here first, e.g. for the pool before the lock-free hand-off (a folder git ignores does not travel):
    #   mkdir gpu_ab && for f in cpp/thread_pool.cpp cpp/thread_pool.hpp; do git show 0181660:$f > gpu_ab/${f#cpp/}; done
    base=/tmp/pool_base; rm -rf "$base"; mkdir -p "$base"; cp -r cpp src CMakeLists.txt "$base"/
    cp "${BASE_POOL:?BASE_POOL names a folder with the baseline thread_pool.cpp and .hpp}"/thread_pool.* "$base"/cpp/
    build_core "$base" "$base/build" || { echo "base build failed"; exit 1; }
    for v in base new; do
      dir=$([ $v = base ] && echo "$base/cpp" || echo cpp)
      g++ -std=c++17 -O2 -I"$dir" benchmarks/gpu/pool_latency.cpp "$dir/thread_pool.cpp" -lpthread -o "/tmp/pool_latency_$v"
      LIMIT=60 run "pool_latency_$v" "/tmp/pool_latency_$v" 1 2 4 8 16
    done
    for rep in 1 2; do
      for v in base new; do
        src=$([ $v = base ] && echo "$base/src" || echo src)
        LIMIT=90 run "pool_ab_bench_world_${v}_r$rep" env PYTHONPATH="$src${PYTHONPATH#src}" python3 benchmarks/bench_world.py \
          --batch 4096 --seconds 1 --scaling-threads 1 2 4 8 16 --scaling-repeats 2 --scaling-seconds 1
      done
    done
    for v in base new; do
      src=$([ $v = base ] && echo "$base/src" || echo src)
      LIMIT=40 run "pool_ab_breakdown_$v" env PYTHONPATH="$src${PYTHONPATH#src}" python3 benchmarks/gpu/world_breakdown.py \
        --batch 4096 --threads 1 16 --seconds 1
    done
    LIMIT=90 run pool_ab_bench_world_new_b16384 python3 benchmarks/bench_world.py --batch 16384 --seconds 1 \
      --scaling-threads 1 2 4 8 16 --scaling-repeats 2 --scaling-seconds 1 ;;
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
