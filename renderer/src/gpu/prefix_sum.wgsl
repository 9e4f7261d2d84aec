// Exclusive prefix sum of a u32 array, one level of the multi-level scan: `scan_blocks` scans
// each block of 1024 values in place and writes the block's total to `sums`; once `sums` has
// been scanned (recursively, by the host), `add_sums` adds each block's offset back.
//
// Additions saturate at 0xffffffff, so a total that would overflow u32 is reported as
// u32::MAX rather than wrapping to a small, plausible number.

struct Params {
    n: u32,
}

@group(0) @binding(0) var<storage, read_write> data: array<u32>;
@group(0) @binding(1) var<storage, read_write> sums: array<u32>;
@group(0) @binding(2) var<uniform> params: Params;

const THREADS: u32 = 256u;
const PER_THREAD: u32 = 4u;
const BLOCK: u32 = 1024u;

var<workgroup> values: array<u32, BLOCK>;
var<workgroup> partial: array<u32, THREADS>;

fn add_sat(a: u32, b: u32) -> u32 {
    let s = a + b;
    return select(s, 0xffffffffu, s < a);
}

@compute @workgroup_size(256)
fn scan_blocks(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let block = wid.x + wid.y * groups.x;
    let base = block * BLOCK;
    if base >= params.n {
        return;
    }
    // Coalesced load into workgroup memory, then each thread scans four consecutive values.
    for (var k = 0u; k < PER_THREAD; k++) {
        let i = base + k * THREADS + lid;
        values[k * THREADS + lid] = select(0u, data[min(i, params.n - 1u)], i < params.n);
    }
    workgroupBarrier();
    var own: array<u32, PER_THREAD>;
    var running = 0u;
    for (var k = 0u; k < PER_THREAD; k++) {
        own[k] = running;
        running = add_sat(running, values[lid * PER_THREAD + k]);
    }
    partial[lid] = running;
    workgroupBarrier();
    // Inclusive Hillis-Steele scan of the per-thread totals.
    for (var offset = 1u; offset < THREADS; offset *= 2u) {
        var left = 0u;
        if lid >= offset {
            left = partial[lid - offset];
        }
        workgroupBarrier();
        partial[lid] = add_sat(partial[lid], left);
        workgroupBarrier();
    }
    var before = 0u;
    if lid > 0u {
        before = partial[lid - 1u];
    }
    for (var k = 0u; k < PER_THREAD; k++) {
        values[lid * PER_THREAD + k] = add_sat(before, own[k]);
    }
    workgroupBarrier();
    for (var k = 0u; k < PER_THREAD; k++) {
        let i = base + k * THREADS + lid;
        if i < params.n {
            data[i] = values[k * THREADS + lid];
        }
    }
    if lid == THREADS - 1u {
        sums[block] = partial[THREADS - 1u];
    }
}

@compute @workgroup_size(256)
fn add_sums(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let block = wid.x + wid.y * groups.x;
    let base = block * BLOCK;
    if base >= params.n {
        return;
    }
    let offset = sums[block];
    for (var k = 0u; k < PER_THREAD; k++) {
        let i = base + k * THREADS + lid;
        if i < params.n {
            data[i] = add_sat(data[i], offset);
        }
    }
}
