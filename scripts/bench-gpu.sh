#!/usr/bin/env bash
# The GPU solver's benchmark (issue 24), prepared to run as one short command on a machine
# with a GPU (the device tool) or here on lavapipe: a 1 m rubber cube of N³ nodes dropped
# 1 m onto the floor, frames stepped on the GPU (and on the CPU up to --cpu-max nodes per
# side); node-substeps per second and ms per frame, one line per size. See docs/benchmarks.md.
#   scripts/bench-gpu.sh                 16³ 32³ 64³, 10 frames (lavapipe-sized)
#   scripts/bench-gpu.sh 64 128 -- 100   the issue's 128³ drop, 100 frames, GPU only
#   scripts/bench-gpu.sh --live 32       the live viewer's case: a 32³ jelly cube swept by
#                                        the manipulator, ms per 1/60 s frame
# Needs a Vulkan (Metal, DX12) driver: NVIDIA's driver brings its own ICD; without a GPU,
# scripts/setup-test-env.sh installs Mesa's lavapipe. It builds with cargo: for the device
# machine, which has none, scripts/device-pack.sh packs gpu_bench and what it needs instead.
set -uo pipefail
cd "$(dirname "$0")/.."
sizes=()
frames=10
live=()
while [ $# -gt 0 ]; do
    if [ "$1" = "--" ]; then frames=$2; shift 2; continue; fi
    if [ "$1" = "--live" ]; then live+=(--live "$2"); shift 2; continue; fi
    sizes+=("$1"); shift
done
[ ${#sizes[@]} -eq 0 ] && [ ${#live[@]} -eq 0 ] && sizes=(16 32 64)
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg), $(nproc) cores"
command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
cargo build --release -p springbake-gpu --example gpu_bench || exit 2
cpu_max=32
for n in ${sizes[@]+"${sizes[@]}"}; do [ "$n" -gt 64 ] && cpu_max=0; done
"${CARGO_TARGET_DIR:-target}/release/examples/gpu_bench" ${sizes[@]+"${sizes[@]}"} ${live[@]+"${live[@]}"} \
    --frames "$frames" --cpu-max "$cpu_max"
