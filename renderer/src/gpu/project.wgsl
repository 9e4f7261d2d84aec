// Projection: one invocation per Gaussian, the same culling rules and arithmetic (operation
// for operation) as `cpu/project.rs`. Writes the compositor's view of the Gaussian, its tile
// rectangle and how many tiles it touches (0 when culled, so it emits no key).

struct Camera {
    // World-to-camera rotation rows (w unused).
    row0: vec4<f32>,
    row1: vec4<f32>,
    row2: vec4<f32>,
    // Camera centre (w unused).
    position: vec4<f32>,
    // fx, fy, cx, cy.
    intrinsics: vec4<f32>,
    // Frustum-clamp limits of x/z and y/z: +x, -x, +y, -y (computed on the host exactly as
    // the CPU computes them).
    limits: vec4<f32>,
    // near, far (zw unused).
    clip: vec4<f32>,
    // Tiles across, tiles down, Gaussian count (w unused).
    grid: vec4<u32>,
}

// One input Gaussian, 64 bytes.
struct Gaussian {
    mean_opacity: vec4<f32>,
    log_scale_confidence: vec4<f32>,
    rotation: vec4<f32>, // x, y, z, w (any norm)
    color: vec4<f32>, // w unused
}

// What the compositor reads, 48 bytes.
struct Splat {
    mean_opacity_depth: vec4<f32>, // mean2d.xy, clamped opacity, camera z
    conic_confidence: vec4<f32>, // conic a, b, c, confidence
    color_radius: vec4<f32>, // rgb, 3-sigma radius (pixels)
}

@group(0) @binding(0) var<storage, read> gaussians: array<Gaussian>;
@group(0) @binding(1) var<uniform> cam: Camera;
@group(0) @binding(2) var<storage, read_write> splats: array<Splat>;
@group(0) @binding(3) var<storage, read_write> rects: array<vec4<u32>>; // min xy, max xy (exclusive)
@group(0) @binding(4) var<storage, read_write> tiles_touched: array<u32>;

const DILATION: f32 = 0.3;
const MIN_QUAT_NORM2: f32 = 1e-24;
const TILE: f32 = 16.0;

// WGSL has no isNan/isInf and compilers may assume finite math: test the exponent bits.
fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

fn is_nan(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7fffffffu) > 0x7f800000u;
}

fn finite4(v: vec4<f32>) -> bool {
    return finite(v.x) && finite(v.y) && finite(v.z) && finite(v.w);
}

// Rows of the rotation matrix of a unit quaternion (x, y, z, w), as `math::quat_to_mat`.
fn quat_to_mat(q: vec4<f32>) -> mat3x3<f32> {
    let x = q.x;
    let y = q.y;
    let z = q.z;
    let w = q.w;
    // Stored as rows: m[r] is row r.
    return mat3x3<f32>(
        vec3<f32>(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)),
        vec3<f32>(2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)),
        vec3<f32>(2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)),
    );
}

fn normalize_quat(q: vec4<f32>) -> vec4<f32> {
    let n2 = q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w;
    if n2 < MIN_QUAT_NORM2 {
        return vec4<f32>(0.0, 0.0, 0.0, 1.0);
    }
    let inv = 1.0 / sqrt(n2);
    return q * inv;
}

// a * b for matrices stored as rows: entry (i, j) is summed left to right over k, as
// `math::mul`.
fn mul_rows(a: mat3x3<f32>, b: mat3x3<f32>) -> mat3x3<f32> {
    return mat3x3<f32>(
        a[0].x * b[0] + a[0].y * b[1] + a[0].z * b[2],
        a[1].x * b[0] + a[1].y * b[1] + a[1].z * b[2],
        a[2].x * b[0] + a[2].y * b[1] + a[2].z * b[2],
    );
}

fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

fn tile_of(v: f32, grid: u32) -> u32 {
    return u32(min(max(floor(v / TILE), 0.0), f32(grid)));
}

fn cull(i: u32) {
    rects[i] = vec4<u32>(0u);
    tiles_touched[i] = 0u;
}

@compute @workgroup_size(256)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = (wid.x + wid.y * groups.x) * 256u + lid;
    if i >= cam.grid.z {
        return;
    }
    let g = gaussians[i];
    if !(finite4(g.mean_opacity) && finite4(g.log_scale_confidence) && finite4(g.rotation)
        && finite(g.color.x) && finite(g.color.y) && finite(g.color.z)) {
        cull(i);
        return;
    }
    let rel = g.mean_opacity.xyz - cam.position.xyz;
    let pc = vec3<f32>(dot3(cam.row0.xyz, rel), dot3(cam.row1.xyz, rel), dot3(cam.row2.xyz, rel));
    let z = pc.z;
    if is_nan(z) || !(z >= cam.clip.x && z <= cam.clip.y) {
        cull(i);
        return;
    }

    // M = R(q) diag(exp(log_scale)); camera covariance (W M)(W M)^T.
    let r = quat_to_mat(normalize_quat(g.rotation));
    let s = exp(g.log_scale_confidence.xyz);
    let m = mat3x3<f32>(r[0] * s, r[1] * s, r[2] * s);
    let w = mat3x3<f32>(cam.row0.xyz, cam.row1.xyz, cam.row2.xyz);
    let wm = mul_rows(w, m);
    let cov = mul_rows(wm, transpose(wm));

    // Perspective Jacobian with the direction clamped to the widened frustum.
    let fx = cam.intrinsics.x;
    let fy = cam.intrinsics.y;
    let u = pc.x / pc.z;
    let v = pc.y / pc.z;
    let uc = min(max(u, -cam.limits.y), cam.limits.x);
    let vc = min(max(v, -cam.limits.w), cam.limits.z);
    let j0 = vec3<f32>(fx / z, 0.0, -fx * uc / z);
    let j1 = vec3<f32>(0.0, fy / z, -fy * vc / z);
    let js0 = vec3<f32>(
        j0.x * cov[0][0] + j0.y * cov[1][0] + j0.z * cov[2][0],
        j0.x * cov[0][1] + j0.y * cov[1][1] + j0.z * cov[2][1],
        j0.x * cov[0][2] + j0.y * cov[1][2] + j0.z * cov[2][2],
    );
    let js1 = vec3<f32>(
        j1.x * cov[0][0] + j1.y * cov[1][0] + j1.z * cov[2][0],
        j1.x * cov[0][1] + j1.y * cov[1][1] + j1.z * cov[2][1],
        j1.x * cov[0][2] + j1.y * cov[1][2] + j1.z * cov[2][2],
    );
    let a = dot3(js0, j0) + DILATION;
    let b = dot3(js0, j1);
    let c = dot3(js1, j1) + DILATION;
    let det = a * c - b * b;
    if !finite(det) || !(det > 0.0) {
        cull(i);
        return;
    }
    let conic = vec3<f32>(c / det, -b / det, a / det);
    let mean2d = vec2<f32>(fx * pc.x / z + cam.intrinsics.z, fy * pc.y / z + cam.intrinsics.w);
    let mid = 0.5 * (a + c);
    let lambda = mid + sqrt(max(mid * mid - det, 0.1));
    let radius = ceil(3.0 * sqrt(lambda));
    if !(finite(conic.x) && finite(conic.y) && finite(conic.z) && finite(mean2d.x)
        && finite(mean2d.y) && finite(radius)) {
        cull(i);
        return;
    }

    // Tile rectangle, clamped in float before the conversion (as `cpu::project::tile_rect`).
    let rect = vec4<u32>(
        tile_of(mean2d.x - radius, cam.grid.x),
        tile_of(mean2d.y - radius, cam.grid.y),
        tile_of(mean2d.x + radius + TILE - 1.0, cam.grid.x),
        tile_of(mean2d.y + radius + TILE - 1.0, cam.grid.y),
    );
    let count = (rect.z - rect.x) * (rect.w - rect.y);
    if count == 0u {
        cull(i);
        return;
    }
    let opacity = min(max(g.mean_opacity.w, 0.0), 1.0);
    splats[i] = Splat(
        vec4<f32>(mean2d, opacity, z),
        vec4<f32>(conic, g.log_scale_confidence.w),
        vec4<f32>(g.color.xyz, radius),
    );
    rects[i] = rect;
    tiles_touched[i] = count;
}
