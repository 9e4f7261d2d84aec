#!/usr/bin/env bash
# Issue 19's measurements on a GPU machine (NVIDIA, Vulkan driver, CUDA 13 driver, no Rust):
# run from the repository root there with gpu_carry/ from `bash scripts/build_cuda.sh` and
# the Vulkan loader packages in .gl/ (see /work/.library/device/README.md). Writes JSON and
# logs to $GPU_RESULTS (default results/gpu/raw). Each step has its own time limit so one failure
# does not cost the rest. Name parts to run only those (render rtests ops model ab profile
# node train gsplat). `gsplat` times gsplat's CUDA rasterizer on the same scenes (scripts/gsplat_bench.py);
# it needs the gsplat wheel in .whl/ (pip download --no-deps gsplat==1.5.3 -d .whl) and
# compiles gsplat's CUDA code first (minutes), in the background while the other parts run.
#   bash scripts/gpu_bench.sh [PART...]
set -uo pipefail
out="${GPU_RESULTS:-results/gpu/raw}"
mkdir -p "$out"
parts=" ${*:-render rtests ops model profile node train gsplat} "
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
# gsplat's CUDA code compiles (one process, every core) while the tests below run; the
# timed parts wait for it so the compiler does not share the machine with them.
want gsplat && {
  log gsplat_compile
  python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/gsplat-*.whl
  export PYTHONPATH=/tmp/site MAX_JOBS=16 TORCH_CUDA_ARCH_LIST=9.0
  (time timeout 400 python3 -c 'from gsplat.cuda._backend import _C; print(_C)') \
    >"$out/gsplat_compile.log" 2>&1 &
  compiling=$!
}
# The renderer's stage tests (each wgpu stage against the CPU) on this GPU.
want rtests && {
log renderer_tests
timeout 60 /tmp/gpu_bin/renderer_tests gpu:: --test-threads 1 >"$out/renderer_tests.txt" 2>&1
echo "rc=$?" >>"$out/renderer_tests.txt"
}
want gsplat && { wait "$compiling"; log gsplat_compiled; }
# The reference scenes: name, width, height, then the other scene flags of `bench render`
# and `render`. (2M is not a reference scene: it shows how the stages grow from 1M to 4M.)
scenes=("121k 544 112" "1m 1920 1080 --scene random --gaussians 1000000"
  "2m 1920 1080 --scene random --gaussians 2000000"
  "4m 1920 1080 --scene random --gaussians 4000000")
# 1. The wgpu rasterizer on the GPU (Vulkan), 50 timed frames each.
want render && for s in "${scenes[@]}"; do
  read -r name w h flags <<<"$s"
  run "render_$name" 90 $bin bench render --no-cpu --runs 50 --warmup 5 \
    --width "$w" --height "$h" $flags
done
# gsplat on the same scenes: the seeded generator's Gaussians written as PLY by `render`.
want gsplat && for s in "${scenes[@]}"; do
  read -r name w h flags <<<"$s"
  timeout 60 $bin render --width "$w" --height "$h" $flags --out "/tmp/scene_$name" \
    >"$out/scene_$name.log" 2>&1
  run "gsplat_$name" 120 python3 scripts/gsplat_bench.py --ply "/tmp/scene_$name/scene.ply" \
    --width "$w" --height "$h"
done
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
# A change against the build before it, on the same machine: with gpu_carry/baseline.xz (a
# `stereosplat` built by build_cuda.sh from the earlier commit), `bench model` per preset
# from each binary in turn, two rounds, so machine-to-machine spread cannot pass for a gain.
want ab && [ -f gpu_carry/baseline.xz ] && {
  xz -dc gpu_carry/baseline.xz >/tmp/gpu_bin/baseline && chmod +x /tmp/gpu_bin/baseline
  for round in 1 2; do
    for preset in tiny small paper; do
      for build in baseline stereosplat; do
        run "ab_${preset}_${build}_$round" 60 "/tmp/gpu_bin/$build" bench model \
          --preset $preset --set device=cuda --runs 20 --warmup 3
      done
    done
  done
}
# Where `tiny`'s time on CUDA goes: every kernel of `bench model` (one warm-up and one timed
# reconstruction, plus each branch once) under Nsight Compute, per kernel name: launches and
# GPU time. Their sum against the wall-clock figure above says how much is kernel work.
want profile && {
  log ncu_tiny
  ncu=$(command -v ncu || ls /opt/nvidia/nsight-compute/*/ncu | head -1)
  timeout 300 "$ncu" --metrics gpu__time_duration.sum --print-summary per-kernel --csv \
    $bin bench model --preset tiny --set device=cuda --runs 1 --warmup 1 \
    >"$out/ncu_tiny.csv" 2>"$out/ncu_tiny.err"
  echo "rc=$?" >>"$out/ncu_tiny.err"
}
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
