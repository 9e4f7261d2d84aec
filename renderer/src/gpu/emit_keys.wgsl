// Key generation: each visible Gaussian writes one (depth, tile) key and its own index for
// every tile its rectangle covers, starting at its scanned offset, so keys come out grouped
// by Gaussian in index order (what makes the stable sort reproduce the CPU's tie-breaking).
//
// The depth word is the f32 bit pattern mapped to an unsigned order (sign flipped for
// positives, all bits for negatives): the IEEE total order `f32::total_cmp` uses on the CPU.

struct Params {
    n: u32,
    grid_x: u32,
}

struct Splat {
    mean_opacity_depth: vec4<f32>,
    conic_confidence: vec4<f32>,
    color_radius: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> splats: array<Splat>;
@group(0) @binding(1) var<storage, read> rects: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> offsets: array<u32>;
@group(0) @binding(3) var<storage, read_write> keys: array<vec2<u32>>;
@group(0) @binding(4) var<storage, read_write> values: array<u32>;
@group(0) @binding(5) var<uniform> params: Params;

fn ordered_bits(x: f32) -> u32 {
    let b = bitcast<u32>(x);
    return select(b | 0x80000000u, ~b, (b & 0x80000000u) != 0u);
}

@compute @workgroup_size(256)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let i = (wid.x + wid.y * groups.x) * 256u + lid;
    if i >= params.n {
        return;
    }
    let rect = rects[i];
    if rect.x >= rect.z || rect.y >= rect.w {
        return;
    }
    let depth = ordered_bits(splats[i].mean_opacity_depth.w);
    var at = offsets[i];
    for (var ty = rect.y; ty < rect.w; ty++) {
        for (var tx = rect.x; tx < rect.z; tx++) {
            keys[at] = vec2<u32>(depth, ty * params.grid_x + tx);
            values[at] = i;
            at++;
        }
    }
}
