// Tile ranges: in the sorted keys, each tile's entries form one run; the first and last
// entry of a run write its start and end (exclusive) into ranges[tile]. Tiles with no
// entries keep the (0, 0) the host cleared them to.

struct Params {
    n: u32,
}

@group(0) @binding(0) var<storage, read> keys: array<vec2<u32>>;
@group(0) @binding(1) var<storage, read_write> ranges: array<vec2<u32>>;
@group(0) @binding(2) var<uniform> params: Params;

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
    let tile = keys[i].y;
    if i == 0u || keys[i - 1u].y != tile {
        ranges[tile].x = i;
    }
    if i + 1u == params.n || keys[i + 1u].y != tile {
        ranges[tile].y = i + 1u;
    }
}
