#!/usr/bin/env bash
# The GPU measurements of results/gpu/ on a GPU machine (NVIDIA, Vulkan driver, CUDA 13 driver, no Rust):
# run from the repository root there with gpu_carry/ from `bash scripts/build_cuda.sh` and
# the Vulkan loader packages in .gl/ (.deb files the script unpacks into /). Writes JSON and
# logs to $GPU_RESULTS (default out/gpu; results/gpu/ keeps the runs cited). Each step has its own time limit so one failure
# does not cost the rest. Name parts to run only those (render rtests ops model ab profile
# scale node train gputrain gsplat). `gsplat` times gsplat's CUDA rasterizer on the same scenes (scripts/gsplat_bench.py);
# it needs the gsplat wheel in .whl/ (pip download --no-deps gsplat==1.5.3 -d .whl) and
# compiles gsplat's CUDA code first (minutes), in the background while the other parts run.
#   bash scripts/gpu_bench.sh [PART...]
set -uo pipefail
out="${GPU_RESULTS:-out/gpu}"
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
# The plain streets `gputrain` trains on, written on 8 cores while the parts before it run
# (their GPU timestamps and kernel times do not count the CPU).
synth_plain=()
want gputrain && for seed in 0 1 2 3 4 5 6 7; do
  timeout 300 $bin research synth --out /tmp/plain --seed $seed --frames 300 --width 272 --height 72 \
    >"$out/synth_plain_$seed.log" 2>&1 &
  synth_plain+=($!)
done
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
# PROFILE_PRESETS picks the presets (default tiny), PROFILE_LIMIT_S the limit of each.
want profile && for preset in ${PROFILE_PRESETS:-tiny}; do
  log "ncu_$preset"
  ncu=$(command -v ncu || ls /opt/nvidia/nsight-compute/*/ncu | head -1)
  timeout "${PROFILE_LIMIT_S:-300}" "$ncu" --metrics gpu__time_duration.sum --print-summary per-kernel --csv \
    $bin bench model --preset "$preset" --set device=cuda --runs 1 --warmup 1 \
    >"$out/ncu_$preset.csv" 2>"$out/ncu_$preset.err"
  echo "rc=$?" >>"$out/ncu_$preset.err"
done
# The rasterizer's cliff between 2M and 4M Gaussians (results/gpu/README.md): a 3M step at
# full HD, and 2M and 4M at the node's 544x112, where each Gaussian makes few tile keys. If the
# per-Gaussian stages (project, emit keys) still jump from 2M to 4M there, the cause goes with
# the Gaussians' buffers, not with the keys' count.
want scale && for s in "2m 1920 1080 2000000" "3m 1920 1080 3000000" "4m 1920 1080 4000000" \
  "2m_small 544 112 2000000" "4m_small 544 112 4000000"; do
  read -r name w h n <<<"$s"
  run "scale_$name" 90 $bin bench render --no-cpu --runs 20 --warmup 3 --width "$w" \
    --height "$h" --scene random --gaussians "$n"
done
# The training drive (also the source of `paper` weights for the node, below).
{ want node || want train; } && log synth && timeout 60 $bin research synth --out /tmp/train_data \
  --seed 0 --frames 160 --width 272 --height 72 >"$out/synth.log" 2>&1
# 4. The node per bin: the model on CUDA, renders on wgpu, 300 frames at the recorded rate.
# A first run on a machine pays the driver's one-time compilation of candle's PTX kernels
# (cached in ~/.nv/ComputeCache); the warm-up takes it outside the timed bins. `paper` has
# no trained weights: one training step writes a file of its shape, so StereoSplat+ at
# `paper` is timed with untrained weights (its Gaussian count is not a trained one's).
want node && {
  run node_warmup 120 $bin bench model --preset tiny --set device=cuda --runs 1 --warmup 1
  run node_paper_weights 60 $bin research train --data /tmp/train_data --preset paper --set device=cuda \
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
  run "train_$preset" 60 $bin research train --data /tmp/train_data --preset $preset --set device=cuda \
    --out "/tmp/run_$preset" --steps 20 --checkpoint-every 1000
  cp "/tmp/run_$preset/log.csv" "$out/train_$preset.csv" 2>/dev/null
done
# 6. A training run of `small` on the GPU: scripts/train_small.sh's three phases (1,600 steps
# with view subsampling, to 3,000 on the first pair, to 8,000 at lr 5e-4 with the relative
# depth losses) on the 8 plain streets of scripts/transfer_data.sh, the recipe
# results/stereosplat_small/README.md chose, for at most GPU_TRAIN_S seconds in all. It
# resumes from gpu_carry/small_run (a run folder carried from an earlier run) and leaves
# the run folder in $out/small_run.tgz, whatever step it reached (SIGTERM checkpoints).
want gputrain && {
  wait "${synth_plain[@]}"
  log synth_plain_done
  resume=()
  [ -f gpu_carry/small_run/checkpoint/state.json ] && cp -r gpu_carry/small_run /tmp/small_run \
    && resume=(--resume)
  deadline=$((SECONDS + ${GPU_TRAIN_S:-300}))
  step() { sed -n 's/.*"step": *\([0-9]*\).*/\1/p' /tmp/small_run/checkpoint/state.json \
    2>/dev/null || echo 0; }
  phase() {
    local left=$((deadline - SECONDS))
    [ "$left" -gt 10 ] || return 0
    log "train_small $*"
    timeout "$left" $bin research train --data /tmp/plain --preset small --set device=cuda \
      --out /tmp/small_run --checkpoint-every 100 "$@" >>"$out/train_small_run.log" 2>&1
    echo "rc=$?" >>"$out/train_small_run.log"
  }
  [ "$(step)" -lt 1600 ] && phase --steps 1600 "${resume[@]}"
  [ "$(step)" -lt 3000 ] && phase --steps 3000 --resume --no-subsample
  phase --steps 8000 --resume --no-subsample --lr 5e-4 --depth-loss relative \
    --rendered-depth-weight 0.5 --estimated-depth-weight 0.5
  tar czf "$out/small_run.tgz" -C /tmp small_run
}
log done
