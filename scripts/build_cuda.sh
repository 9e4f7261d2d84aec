#!/usr/bin/env bash
# Builds, on a machine WITHOUT a GPU, what a GPU machine without a Rust toolchain runs
# (results/gpu/): `stereosplat` and the GPU-against-CPU op tests with the `cuda` feature, and the
# renderer's wgpu-against-CPU stage tests, stripped and xz-compressed into gpu_carry/
# (git-ignored; 16 MB instead of 90 for the node). What it needs, all from the registries:
# - nvcc 13.0 and its headers (pip `nvidia-cuda-nvcc`, `-nvvm`, `-crt`, `-runtime`, `-cccl`,
#   all 13.0 so the PTX is 9.0, which a CUDA 13.0 driver loads);
# - the CUDA libraries cudarc and candle-kernels link against (pip `nvidia-cublas`,
#   `-curand`, `-cuda-nvrtc`, `-cuda-runtime`), given unversioned names in $LINK;
# - libcuda.so, the driver, which only a GPU machine has: linked here against a stub of
#   the same name (SONAME libcuda.so.1, one empty function per driver symbol cudarc
#   declares); at run time the GPU machine's real driver is loaded instead.
#   bash scripts/build_cuda.sh [LINK_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
link="${1:-/opt/cudalink}"
python3 -m pip install -q "nvidia-cuda-nvcc==13.0.88" "nvidia-nvvm==13.0.88" \
  "nvidia-cuda-crt==13.0.88" "nvidia-cuda-runtime==13.0.96" "nvidia-cuda-cccl==13.0.85"
python3 -m pip install -q --target "$link/py" "nvidia-cublas==13.0.*" nvidia-curand \
  "nvidia-cuda-nvrtc==13.0.*"
site=$(python3 -c 'import nvidia.cu13, os; print(os.path.dirname(nvidia.cu13.__path__[0]))')
cuda="$site/cu13"
mkdir -p "$link/lib"
for lib in nvrtc.so.13 curand.so.10 cublasLt.so.13 cublas.so.13; do
  ln -sf "$link/py/nvidia/cu13/lib/lib$lib" "$link/lib/lib${lib%%.so*}.so"
done
ln -sf "$cuda/lib/libcudart.so.13" "$link/lib/libcudart.so"  # candle-kernels' MoE kernels
# A fresh machine has no crate sources yet; the stub is made from cudarc's.
cargo fetch >/dev/null
cudarc=$(ls -d "${CARGO_HOME:-$HOME/.cargo}"/registry/src/*/cudarc-0.19.10 | head -1)
grep -o 'pub unsafe fn cu[A-Za-z0-9_]*' "$cudarc/src/driver/sys/mod.rs" | awk '{print $4}' |
  sort -u | sed 's/.*/void &(void){}/' >"$link/libcuda_stub.c"
gcc -shared -fPIC -Wl,-soname,libcuda.so.1 -o "$link/lib/libcuda.so" "$link/libcuda_stub.c"
export PATH="$cuda/bin:$PATH" CUDA_HOME="$cuda" CUDA_COMPUTE_CAP=90
export CARGO_TARGET_DIR=target/cuda CARGO_PROFILE_RELEASE_DEBUG=false
export CARGO_PROFILE_RELEASE_STRIP=true RUSTFLAGS="-L native=$link/lib"
cargo build --release -p node --features cuda
tests=$(cargo test --release -p model --features cuda --test cuda_ops --no-run \
  --message-format=json | sed -n 's/.*"executable":"\([^"]*cuda_ops[^"]*\)".*/\1/p' | tail -1)
# The renderer's own tests: every wgpu stage against the CPU, on the GPU's Vulkan driver.
rtests=$(cargo test --release -p renderer --lib --no-run --message-format=json |
  sed -n 's/.*"executable":"\([^"]*renderer-[^"]*\)".*/\1/p' | tail -1)
mkdir -p gpu_carry
xz -T0 -6 -c target/cuda/release/stereosplat >gpu_carry/stereosplat.xz
xz -T0 -6 -c "$tests" >gpu_carry/cuda_ops.xz
xz -T0 -6 -c "$rtests" >gpu_carry/renderer_tests.xz
ls -la gpu_carry
