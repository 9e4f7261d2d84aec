// One pass of a stable LSD radix sort of (key, value) pairs on a 4-bit digit. Keys are
// vec2<u32>: x is the low word (ordered depth bits), y the high word (tile id).
//
// `histogram`: each block of 1024 keys counts its digits into hist[digit * blocks + block].
// The host then scans `hist` (exclusively, with the prefix-sum stage), so each entry becomes
// where that block's keys with that digit start in the output.
// `scatter`: each key goes to that start plus its rank among the block's earlier keys with
// the same digit, which keeps equal digits in input order: the sort is stable.
//
// The ranks come from one workgroup scan of per-invocation digit counts packed as sixteen
// 16-bit counters in eight u32 (a block's counts never exceed 1024). No subgroup operations.

struct Params {
    n: u32,
    shift: u32,
    word: u32, // 0: sort on key.x, 1: on key.y
    blocks: u32,
}

@group(0) @binding(0) var<storage, read> keys_in: array<vec2<u32>>;
@group(0) @binding(1) var<storage, read> values_in: array<u32>;
@group(0) @binding(2) var<storage, read_write> keys_out: array<vec2<u32>>;
@group(0) @binding(3) var<storage, read_write> values_out: array<u32>;
@group(0) @binding(4) var<storage, read_write> hist: array<u32>;
@group(0) @binding(5) var<uniform> params: Params;

const THREADS: u32 = 256u;
const ITEMS: u32 = 4u; // keys per invocation
const BLOCK: u32 = 1024u; // THREADS * ITEMS
const RADIX: u32 = 16u;

var<workgroup> counts: array<atomic<u32>, RADIX>;
var<workgroup> ranks_lo: array<vec4<u32>, THREADS>;
var<workgroup> ranks_hi: array<vec4<u32>, THREADS>;

fn digit_of(key: vec2<u32>) -> u32 {
    return (select(key.x, key.y, params.word == 1u) >> params.shift) & (RADIX - 1u);
}

// The 16-bit counter of `digit` in a packed set of sixteen (digits 0-7 in `lo`).
fn counter(lo: vec4<u32>, hi: vec4<u32>, digit: u32) -> u32 {
    let word = digit >> 1u;
    let packed = select(hi[(word - 4u) & 3u], lo[word & 3u], word < 4u);
    return (packed >> ((digit & 1u) * 16u)) & 0xffffu;
}

@compute @workgroup_size(256)
fn histogram(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let block = wid.x + wid.y * groups.x;
    if block >= params.blocks {
        return;
    }
    if lid < RADIX {
        atomicStore(&counts[lid], 0u);
    }
    workgroupBarrier();
    for (var k = 0u; k < ITEMS; k++) {
        let i = block * BLOCK + k * THREADS + lid;
        if i < params.n {
            atomicAdd(&counts[digit_of(keys_in[i])], 1u);
        }
    }
    workgroupBarrier();
    if lid < RADIX {
        hist[lid * params.blocks + block] = atomicLoad(&counts[lid]);
    }
}

// Each invocation ranks ITEMS consecutive keys: first among themselves, then (one workgroup
// scan) after all keys of earlier invocations, so ranks follow input order.
@compute @workgroup_size(256)
fn scatter(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    let block = wid.x + wid.y * groups.x;
    if block >= params.blocks {
        return;
    }
    let base = block * BLOCK + lid * ITEMS;
    var keys: array<vec2<u32>, ITEMS>;
    var digits: array<u32, ITEMS>;
    var within: array<u32, ITEMS>; // rank among this invocation's earlier keys
    var own_lo = vec4<u32>(0u);
    var own_hi = vec4<u32>(0u);
    for (var k = 0u; k < ITEMS; k++) {
        if base + k < params.n {
            let key = keys_in[base + k];
            let digit = digit_of(key);
            keys[k] = key;
            digits[k] = digit;
            within[k] = counter(own_lo, own_hi, digit);
            let one = 1u << ((digit & 1u) * 16u);
            let word = digit >> 1u;
            if word < 4u {
                own_lo[word] += one;
            } else {
                own_hi[word - 4u] += one;
            }
        }
    }
    var lo = own_lo;
    var hi = own_hi;
    ranks_lo[lid] = lo;
    ranks_hi[lid] = hi;
    workgroupBarrier();
    // Inclusive Hillis-Steele scan of the packed counters.
    for (var offset = 1u; offset < THREADS; offset *= 2u) {
        var left_lo = vec4<u32>(0u);
        var left_hi = vec4<u32>(0u);
        if lid >= offset {
            left_lo = ranks_lo[lid - offset];
            left_hi = ranks_hi[lid - offset];
        }
        workgroupBarrier();
        lo += left_lo;
        hi += left_hi;
        ranks_lo[lid] = lo;
        ranks_hi[lid] = hi;
        workgroupBarrier();
    }
    let before_lo = lo - own_lo;
    let before_hi = hi - own_hi;
    for (var k = 0u; k < ITEMS; k++) {
        if base + k < params.n {
            let digit = digits[k];
            let rank = counter(before_lo, before_hi, digit) + within[k];
            let dst = hist[digit * params.blocks + block] + rank;
            keys_out[dst] = keys[k];
            values_out[dst] = values_in[base + k];
        }
    }
}
