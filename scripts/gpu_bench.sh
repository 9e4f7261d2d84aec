#!/usr/bin/env bash
# Issue 19's measurements on a GPU machine (NVIDIA, Vulkan driver, CUDA 13 driver, no Rust):
# run from the repository root there with gpu_carry/ from `bash scripts/build_cuda.sh` and
# the Vulkan loader packages in .gl/ (see /work/.library/device/README.md). Writes JSON and
# logs to $GPU_RESULTS (default results/gpu/raw). Each step has its own time limit so one failure
# does not cost the rest. Name parts to run only those (render rtests ops model node train).
#   bash scripts/gpu_bench.sh [PART...]
set -uo pipefail
out="${GPU_RESULTS:-results/gpu/raw}"
mkdir -p "$out"
parts=" ${*:-render rtests ops model node train} "
want() { [[ $parts == *" $1 "* ]]; }
log() { echo "== $(date +%T) $*" | tee -a "$out/steps.log"; }
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
# The binaries find model/weights through the path they were built in.
built=/work/main
[ -e "$built/model/weights" ] || { mkdir -p "$(dirname "$built")"; ln -sfn "$PWD" "$built"; }
site=$(python3 -c 'import nvidia.cu13, os; print(os.path.dirname(nvidia.cu13.__path__[0]))' 2>/dev/null)
export LD_LIBRARY_PATH="$site/cu13/lib:${LD_LIBRARY_PATH:-}"
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
[ -f "$icd" ] && export VK_DRIVER_FILES="$icd"
export WGPU_BACKEND=vulkan XDG_RUNTIME_DIR=/tmp/xdg
mkdir -p -m 700 /tmp/xdg
nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv >"$out/gpu.csv"
nproc >>"$out/gpu.csv"
ls /usr/local/nvidia/share/vulkan/icd.d /usr/share/vulkan/icd.d /etc/vulkan/icd.d >>"$out/gpu.csv" 2>&1
mkdir -p /tmp/gpu_bin
for exe in stereosplat cuda_ops renderer_tests; do
  xz -dc "gpu_carry/$exe.xz" >"/tmp/gpu_bin/$exe" && chmod +x "/tmp/gpu_bin/$exe"
done
bin=/tmp/gpu_bin/stereosplat
run() { # NAME LIMIT CMD...: stdout to NAME.json, stderr to NAME.err
  local name=$1 limit=$2
  shift 2
  log "$name"
  timeout "$limit" "$@" >"$out/$name.json" 2>"$out/$name.err"
  echo "rc=$?" >>"$out/$name.err"
}
# 1. The wgpu rasterizer on the GPU (Vulkan): the reference scenes, 50 timed frames each.
want render && {
run render_121k 45 $bin bench render --no-cpu --runs 50 --warmup 5
run render_1m 60 $bin bench render --no-cpu --runs 50 --warmup 5 --scene random \
  --gaussians 1000000 --width 1920 --height 1080
run render_4m 90 $bin bench render --no-cpu --runs 50 --warmup 5 --scene random \
  --gaussians 4000000 --width 1920 --height 1080
}
# The renderer's stage tests (each wgpu stage against the CPU) on this GPU.
want rtests && {
log renderer_tests
timeout 60 /tmp/gpu_bin/renderer_tests gpu:: --test-threads 1 >"$out/renderer_tests.txt" 2>&1
echo "rc=$?" >>"$out/renderer_tests.txt"
}
# 2. Every custom op, LPIPS, the enhancer and the network: GPU against CPU.
want ops && {
log cuda_ops
timeout 120 /tmp/gpu_bin/cuda_ops --test-threads 1 --nocapture >"$out/cuda_ops.txt" 2>&1
echo "rc=$?" >>"$out/cuda_ops.txt"
}
# 3. The network per preset on CUDA (one 544x112 pair), and tiny on this machine's CPU.
want model && for preset in tiny small paper; do
  run "model_$preset" 60 $bin bench model --preset $preset --set device=cuda --runs 20 --warmup 3
done
want model && run model_tiny_cpu 60 $bin bench model --preset tiny --runs 10
# The training drive (also the source of `paper` weights for the node, below).
{ want node || want train; } && log synth && timeout 60 $bin synth --out /tmp/train_data \
  --seed 0 --frames 160 --width 272 --height 72 >"$out/synth.log" 2>&1
# 4. The node per bin: the model on CUDA, renders on wgpu, 300 frames at the recorded rate.
# A first run on a machine pays the driver's one-time compilation of candle's PTX kernels
# (cached in ~/.nv/ComputeCache); the warm-up takes it outside the timed bins. `paper` has
# no trained weights: one training step writes a file of its shape, so StereoSplat+ at
# `paper` is timed with untrained weights (its Gaussian count is not a trained one's).
want node && {
  run node_warmup 120 $bin bench model --preset tiny --set device=cuda --runs 1 --warmup 1
  run node_paper_weights 60 $bin train --data /tmp/train_data --preset paper --set device=cuda \
    --out /tmp/run_paper1 --steps 1
  for preset in tiny tiny-plus; do
    run "node_$preset" 100 $bin bench node --frames 300 --rate 1 --preset $preset \
      --set device=cuda --renders gpu
  done
  run node_paper-plus 100 $bin bench node --frames 300 --rate 1 --preset paper --weights \
    /tmp/run_paper1/stereosplat_paper.safetensors --set device=cuda --set progressive=true \
    --renders gpu
}
# 5. Training steps per second on CUDA per preset (same generated drive).
want train && for preset in tiny small paper; do
  run "train_$preset" 60 $bin train --data /tmp/train_data --preset $preset --set device=cuda \
    --out "/tmp/run_$preset" --steps 20 --checkpoint-every 1000
  cp "/tmp/run_$preset/log.csv" "$out/train_$preset.csv" 2>/dev/null
done
log done
