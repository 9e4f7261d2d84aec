// Compositing: one 16x16 workgroup per tile, one invocation per pixel. The tile's sorted
// splats are loaded in batches of 256 into workgroup memory and blended front to back with
// exactly the rules of `cpu/composite.rs`: skip where the power is positive or alpha is
// below 1/255, clamp alpha to 0.99, stop before the splat that would take transmittance
// below 1e-4, background behind with the final transmittance. The workgroup stops loading
// once every pixel of the tile is done.
//
// Output planes in one buffer of `pixels` entries each: rgb (interleaved, 3 planes' worth),
// normalised depth, raw depth, alpha, confidence, surface depth (the depth of the splat whose
// blend takes transmittance to `surface.x`, else of the one that takes it to one half, else 0).

struct Params {
    width: u32,
    height: u32,
    grid_x: u32,
    pixels: u32,
    background: vec4<f32>,
    // x: the transmittance at which the surface depth is taken (1 - surface opacity).
    surface: vec4<f32>,
}

struct Splat {
    mean_opacity_depth: vec4<f32>,
    conic_confidence: vec4<f32>,
    color_radius: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> splats: array<Splat>;
@group(0) @binding(1) var<storage, read> sorted: array<u32>;
@group(0) @binding(2) var<storage, read> ranges: array<vec2<u32>>;
@group(0) @binding(3) var<storage, read_write> image: array<f32>;
@group(0) @binding(4) var<uniform> params: Params;

const BATCH: u32 = 256u;
const MAX_ALPHA: f32 = 0.99;
const MIN_ALPHA: f32 = 1.0 / 255.0;
const MIN_TRANSMITTANCE: f32 = 1e-4;
const MIN_DEPTH_ALPHA: f32 = 1e-6;

// The batch, split so the test for whether a splat touches a pixel reads 8 floats and the
// colour, depth and confidence are read only when it contributes.
var<workgroup> batch_shape: array<vec4<f32>, BATCH>; // mean2d.xy, conic a, conic b
var<workgroup> batch_weight: array<vec4<f32>, BATCH>; // conic c, opacity, depth, confidence
var<workgroup> batch_color: array<vec4<f32>, BATCH>; // rgb, unused
var<workgroup> done_count: atomic<u32>;
var<workgroup> done_snapshot: u32;

@compute @workgroup_size(16, 16)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(local_invocation_id) local: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let tile = wid.x + wid.y * params.grid_x;
    let x = wid.x * 16u + local.x;
    let y = wid.y * 16u + local.y;
    let inside = x < params.width && y < params.height;
    let px = f32(x);
    let py = f32(y);

    let range = ranges[tile];
    let batches = (range.y - range.x + BATCH - 1u) / BATCH;
    if lid == 0u {
        atomicStore(&done_count, 0u);
    }
    workgroupBarrier();
    var done = !inside;
    if done {
        atomicAdd(&done_count, 1u);
    }
    var t = 1.0;
    var rgb = vec3<f32>(0.0);
    var depth_raw = 0.0;
    var confidence = 0.0;
    var surface_depth = 0.0;
    var half_depth = 0.0;

    for (var b = 0u; b < batches; b++) {
        workgroupBarrier();
        if lid == 0u {
            done_snapshot = atomicLoad(&done_count);
        }
        if workgroupUniformLoad(&done_snapshot) == BATCH {
            break;
        }
        let start = range.x + b * BATCH;
        if start + lid < range.y {
            let s = splats[sorted[start + lid]];
            batch_shape[lid] = vec4<f32>(s.mean_opacity_depth.xy, s.conic_confidence.xy);
            batch_weight[lid] = vec4<f32>(s.conic_confidence.z, s.mean_opacity_depth.zw, s.conic_confidence.w);
            batch_color[lid] = s.color_radius;
        }
        workgroupBarrier();
        let count = min(BATCH, range.y - start);
        for (var j = 0u; j < count && !done; j++) {
            let shape = batch_shape[j];
            let weight = batch_weight[j];
            let dx = shape.x - px;
            let dy = shape.y - py;
            let power = -0.5 * (shape.z * dx * dx + weight.x * dy * dy) - shape.w * dx * dy;
            if power > 0.0 {
                continue;
            }
            let alpha = min(MAX_ALPHA, weight.y * exp(power));
            if alpha < MIN_ALPHA {
                continue;
            }
            let next_t = t * (1.0 - alpha);
            if next_t < MIN_TRANSMITTANCE {
                done = true;
                atomicAdd(&done_count, 1u);
                break;
            }
            if t > 0.5 && next_t <= 0.5 {
                half_depth = weight.z;
            }
            if t > params.surface.x && next_t <= params.surface.x {
                surface_depth = weight.z;
            }
            let w = alpha * t;
            rgb += w * batch_color[j].xyz;
            depth_raw += w * weight.z;
            confidence += w * weight.w;
            t = next_t;
        }
    }

    if inside {
        let p = y * params.width + x;
        let n = params.pixels;
        let alpha = 1.0 - t;
        let color = rgb + t * params.background.xyz;
        image[3u * p] = color.x;
        image[3u * p + 1u] = color.y;
        image[3u * p + 2u] = color.z;
        image[3u * n + p] = select(0.0, depth_raw / alpha, alpha > MIN_DEPTH_ALPHA);
        image[4u * n + p] = depth_raw;
        image[5u * n + p] = alpha;
        image[6u * n + p] = confidence;
        image[7u * n + p] = select(half_depth, surface_depth, surface_depth > 0.0);
    }
}
