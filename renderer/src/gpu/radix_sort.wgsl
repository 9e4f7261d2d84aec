// One pass of a stable LSD radix sort of (key, value) pairs on an 8-bit digit. Keys are
// vec2<u32>: x is the low word (ordered depth bits), y the high word (tile id).
//
// `histogram`: each block of 1024 keys counts its digits into hist[digit * blocks + block].
// The host then scans `hist` (exclusively, with the prefix-sum stage), so each entry becomes
// where that block's keys with that digit start in the output.
// `scatter`: each block first sorts its own keys by the digit, stably, in workgroup memory:
// one split per 4-bit part of the digit, lowest part first. A split ranks every key among
// the block's earlier keys with the same 4-bit value through one workgroup scan of
// per-invocation counts packed as sixteen 16-bit counters in eight u32 (a block's counts
// never exceed 1024). The block's keys then leave in that order, each to its digit's start
// plus its place in the digit's run: neighbouring invocations write neighbouring addresses,
// and equal digits keep input order, so the sort is stable. No subgroup operations.

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
const DIGIT_BITS: u32 = 8u;
const RADIX: u32 = 1u << DIGIT_BITS;
const SPLITS: u32 = DIGIT_BITS / 4u;

var<workgroup> counts: array<atomic<u32>, RADIX>;
var<workgroup> ranks_lo: array<vec4<u32>, THREADS>;
var<workgroup> ranks_hi: array<vec4<u32>, THREADS>;
// The block's keys as (digit << 16) | index within the block, in the current split's order.
var<workgroup> order: array<u32, BLOCK>;
// Where each digit's run starts in the block's sorted order.
var<workgroup> run_start: array<u32, RADIX>;

fn digit_of(key: vec2<u32>) -> u32 {
    return (select(key.x, key.y, params.word == 1u) >> params.shift) & (RADIX - 1u);
}


// Sixteen 16-bit counters packed in eight u32, parts 0-7 in `lo`.
struct Packed {
    lo: vec4<u32>,
    hi: vec4<u32>,
}

// The 16-bit counter of `part`.
fn counter(c: Packed, part: u32) -> u32 {
    let word = part >> 1u;
    let packed = select(c.hi[(word - 4u) & 3u], c.lo[word & 3u], word < 4u);
    return (packed >> ((part & 1u) * 16u)) & 0xffffu;
}

// Adds `value` to the counter of `part`.
fn add(c: ptr<function, Packed>, part: u32, value: u32) {
    let word = part >> 1u;
    let v = value << ((part & 1u) * 16u);
    if word < 4u {
        (*c).lo[word] += v;
    } else {
        (*c).hi[word - 4u] += v;
    }
}

// Each counter replaced by the sum of the counters below it: where each part's keys start.
fn exclusive(c: Packed) -> Packed {
    var out = Packed(vec4<u32>(0u), vec4<u32>(0u));
    var sum = 0u;
    for (var part = 0u; part < 16u; part++) {
        add(&out, part, sum);
        sum += counter(c, part);
    }
    return out;
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
    for (var d = lid; d < RADIX; d += THREADS) {
        atomicStore(&counts[d], 0u);
    }
    workgroupBarrier();
    for (var k = 0u; k < ITEMS; k++) {
        let i = block * BLOCK + k * THREADS + lid;
        if i < params.n {
            atomicAdd(&counts[digit_of(keys_in[i])], 1u);
        }
    }
    workgroupBarrier();
    for (var d = lid; d < RADIX; d += THREADS) {
        hist[d * params.blocks + block] = atomicLoad(&counts[d]);
    }
}

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
    let base = block * BLOCK;
    // Invocation `lid` holds block positions lid * ITEMS + k, so (invocation, item) order is
    // input order. Keys past the end take the largest digit; being last in input order, they
    // stay behind every real key and are not written.
    var entries: array<u32, ITEMS>;
    for (var k = 0u; k < ITEMS; k++) {
        let i = lid * ITEMS + k;
        var digit = RADIX - 1u;
        if base + i < params.n {
            digit = digit_of(keys_in[base + i]);
        }
        entries[k] = (digit << 16u) | i;
    }
    for (var split = 0u; split < SPLITS; split++) {
        let shift = 16u + 4u * split;
        var within: array<u32, ITEMS>; // rank among this invocation's earlier keys
        var own = Packed(vec4<u32>(0u), vec4<u32>(0u));
        for (var k = 0u; k < ITEMS; k++) {
            let part = (entries[k] >> shift) & 15u;
            within[k] = counter(own, part);
            add(&own, part, 1u);
        }
        var lo = own.lo;
        var hi = own.hi;
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
        let starts = exclusive(Packed(ranks_lo[THREADS - 1u], ranks_hi[THREADS - 1u]));
        let before = Packed(lo - own.lo, hi - own.hi);
        for (var k = 0u; k < ITEMS; k++) {
            let part = (entries[k] >> shift) & 15u;
            let at = counter(starts, part) + counter(before, part) + within[k];
            order[at] = entries[k];
        }
        workgroupBarrier();
        for (var k = 0u; k < ITEMS; k++) {
            entries[k] = order[lid * ITEMS + k];
        }
        // The next split's first barrier keeps these reads before its writes to `order`.
    }
    // Sorted; read position p = k * THREADS + lid so neighbours write neighbouring addresses.
    for (var k = 0u; k < ITEMS; k++) {
        let p = k * THREADS + lid;
        let digit = order[p] >> 16u;
        if p == 0u || (order[p - 1u] >> 16u) != digit {
            run_start[digit] = p;
        }
    }
    workgroupBarrier();
    for (var k = 0u; k < ITEMS; k++) {
        let p = k * THREADS + lid;
        let entry = order[p];
        let i = entry & 0xffffu;
        if base + i < params.n {
            let digit = entry >> 16u;
            let dst = hist[digit * params.blocks + block] + p - run_start[digit];
            keys_out[dst] = keys_in[base + i];
            values_out[dst] = values_in[base + i];
        }
    }
}
