// The bilinear sampler's three kernels on CUDA, compiled at run time by NVRTC
// (bilinear_cuda.rs): the twins of the CPU kernels in bilinear.rs, with the same taps, the
// same rule for points outside the image or NaN (zero sample, zero gradient) and the same
// order of summation. One thread per output value; one launch per op instead of the ~95 of
// the gather formulation.

template <typename T> struct Taps {
  int idx[4];  // flat index into an H x W plane; -1 for a tap outside the image
  T w[4];      // bilinear weights
  T dx[4];     // their derivatives with respect to x
  T dy[4];     // and to y
};

__device__ float floor_of(float v) { return floorf(v); }
__device__ double floor_of(double v) { return floor(v); }

template <typename T> __device__ Taps<T> taps_at(T x, T y, int w, int h) {
  Taps<T> t;
  for (int k = 0; k < 4; ++k) {
    t.idx[k] = -1;
    t.w[k] = t.dx[k] = t.dy[k] = T(0);
  }
  // Written so that NaN fails it; bounds the floors below to small integers.
  if (!(x > T(-1) && x < T(w) && y > T(-1) && y < T(h))) return t;
  const T x0 = floor_of(x), y0 = floor_of(y);
  const T ax = x - x0, ay = y - y0;
  const int ix = int(x0), iy = int(y0);
  for (int k = 0; k < 4; ++k) {
    const int cx = k & 1, cy = k >> 1;
    const int xi = ix + cx, yi = iy + cy;
    if (xi < 0 || yi < 0 || xi >= w || yi >= h) continue;
    const T wx = cx ? ax : T(1) - ax, sx = cx ? T(1) : T(-1);
    const T wy = cy ? ay : T(1) - ay, sy = cy ? T(1) : T(-1);
    t.idx[k] = yi * w + xi;
    t.w[k] = wx * wy;
    t.dx[k] = sx * wy;
    t.dy[k] = sy * wx;
  }
  return t;
}

__device__ long long thread_index() { return blockIdx.x * (long long)blockDim.x + threadIdx.x; }

// The taps of value i of an (N, C, P) output: those of its point in grid (N, P, 2).
template <typename T>
__device__ Taps<T> taps_of_value(const T* grid, long long i, int c, int h, int w, int p) {
  const long long point = i / p / c * p + i % p;
  return taps_at(grid[2 * point], grid[2 * point + 1], w, h);
}

// out (N, C, P) from input (N, C, H, W) and grid (N, P, 2): one thread per output value.
template <typename T>
__device__ void sample(const T* input, const T* grid, T* out, int c, int h, int w, int p,
                       long long total) {
  const long long i = thread_index();
  if (i >= total) return;
  const long long plane = i / p;
  const Taps<T> t = taps_of_value(grid, i, c, h, w, p);
  const T* src = input + plane * (long long)h * w;
  T s = T(0);
  for (int k = 0; k < 4; ++k) s += t.w[k] * (t.idx[k] < 0 ? T(0) : src[t.idx[k]]);
  out[i] = s;
}

// d input (N, C, H, W), zeroed by the caller, from grid (N, P, 2) and d out (N, C, P): each
// output gradient scattered onto its taps inside the image (atomic adds).
template <typename T>
__device__ void input_grad(const T* grid, const T* grad, T* out, int c, int h, int w, int p,
                           long long total) {
  const long long i = thread_index();
  if (i >= total) return;
  const Taps<T> t = taps_of_value(grid, i, c, h, w, p);
  T* dst = out + i / p * (long long)h * w;
  for (int k = 0; k < 4; ++k)
    if (t.idx[k] >= 0) atomicAdd(dst + t.idx[k], t.w[k] * grad[i]);
}

// d grid (N, P, 2) from input (N, C, H, W), grid and d out (N, C, P): one thread per point,
// the derivative of its blend summed over channels.
template <typename T>
__device__ void grid_grad(const T* input, const T* grid, const T* grad, T* out, int c, int h,
                          int w, int p, long long total) {
  const long long i = thread_index();
  if (i >= total) return;
  const long long n = i / p;
  const int q = int(i % p);
  const Taps<T> t = taps_at(grid[2 * i], grid[2 * i + 1], w, h);
  T gx = T(0), gy = T(0);
  for (int ci = 0; ci < c; ++ci) {
    const long long plane = n * c + ci;
    const T* src = input + plane * (long long)h * w;
    const T g = grad[plane * p + q];
    for (int k = 0; k < 4; ++k) {
      const T v = g * (t.idx[k] < 0 ? T(0) : src[t.idx[k]]);
      gx += t.dx[k] * v;
      gy += t.dy[k] * v;
    }
  }
  out[2 * i] = gx;
  out[2 * i + 1] = gy;
}

#define INSTANTIATE(T, SUFFIX)                                                              \
  extern "C" __global__ void grid_sample_##SUFFIX(const T* input, const T* grid, T* out,    \
                                                  int c, int h, int w, int p,               \
                                                  long long total) {                        \
    sample<T>(input, grid, out, c, h, w, p, total);                                         \
  }                                                                                         \
  extern "C" __global__ void grid_sample_input_grad_##SUFFIX(                               \
      const T* grid, const T* grad, T* out, int c, int h, int w, int p, long long total) {  \
    input_grad<T>(grid, grad, out, c, h, w, p, total);                                      \
  }                                                                                         \
  extern "C" __global__ void grid_sample_grid_grad_##SUFFIX(                                \
      const T* input, const T* grid, const T* grad, T* out, int c, int h, int w, int p,     \
      long long total) {                                                                    \
    grid_grad<T>(input, grid, grad, out, c, h, w, p, total);                                \
  }

INSTANTIATE(float, f32)
INSTANTIATE(double, f64)
