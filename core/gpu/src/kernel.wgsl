// The relight sum on the GPU over the tiled stack: image = Σ weight · scale · value, one
// workgroup per 16×16 tile and one invocation per pixel. See kernel.rs for the host side,
// tiles.rs for the tables and layout.rs for the value chunks.
//
// Per pixel the order of operations is the CPU tiled sum's (core/engine/src/relight/
// tiled_sum.rs): the tile's per-pixel entries in layer order, grey entries into one
// accumulator and RGB entries into another, each `acc = fma(weight · scale, value, acc)`,
// then `pixel = (grey + rgb)` on a full relight or `pixel += (grey + rgb)` on an
// incremental one. The accumulators live in registers: the image is read at most once and
// written once.
//
// The entries are read in batches of BATCH: each invocation loads one entry's record, its
// weight and its segment mask into workgroup memory, and after a barrier the whole workgroup
// walks the batch from there. Otherwise every invocation reads every entry's record and then
// its weight from the storage buffers, two dependent reads per entry before its values; a
// tile holds hundreds of entries at several editable materials. The tables list a tile's
// per-pixel entries before its lattice entries (tiles.rs), and each kind has a loop of its
// own: they add into different accumulators, so neither order changes a sum.
//
// Lattice entries (lattice.rs, core/engine/src/stack/tiled/lattice.rs) are summed as the
// CPU sums them: each adds `weight · scale · coefficient` into per-(segment, lattice node,
// channel) accumulators, and after a barrier each pixel adds its segment's ≤ 4 hat nodes
// into its RGB accumulator, after every RGB entry and before `grey + rgb`, as the CPU's
// expansion does. A slot's place among an entry's coefficients is found once per tile, and
// its sum kept in a register. Where a tile's slots fill at most half the workgroup (75 of
// 256 at the presets' 25-node lattices), the invocations form up to MAX_LANES groups of one
// invocation per slot that sum every `lanes`-th entry side by side, and the groups' sums
// are added per slot in group order: the same additions as the CPU's, grouped differently
// (so equal to rounding). Larger lattices take one group, and an invocation also owns slots
// lid + 256, … in workgroup memory; every slot's additions come from one invocation in
// entry order, without atomics.
//
// Full relight: `weights` holds every layer's weight. Incremental: it holds the weight
// changes of the edited layers and zero elsewhere; an entry of zero weight is skipped
// unread, and a tile where nothing was added is left as it is.

struct Params {
    width: u32,
    height: u32,
    tiles_x: u32,
    // Tiles of this dispatch: first_tile .. first_tile + tile_count (one bind group's).
    first_tile: u32,
    tile_count: u32,
    // 1: write the sum; 0: add it to the current image.
    reset: u32,
    // 0: two f16 per word, low half first; 1: one f32 per word.
    format: u32,
    // Word of `tables` where the entry records start (after the tile starts).
    entries_at: u32,
}

// An entry record (tiles.rs): 4 words.
struct Entry {
    layer: u32,
    // Channels, kind and chunk slot, packed as tiles.rs's entry_flags (see `channels_of`,
    // `kind_of`, `chunk_of`).
    flags: u32,
    scale: f32,
    // First sample of the entry in its chunk.
    offset: u32,
}

const TILE: u32 = 16u;
const INVOCATIONS: u32 = 256u;
const KIND_LATTICE: u32 = 1u;
// Three floats for each of lattice.rs's MAX_NODE_SLOTS (segment, node) pairs.
const NODE_FLOATS: u32 = 3072u;

@group(0) @binding(0) var<storage, read_write> image: array<vec4<f32>>;
@group(0) @binding(1) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> weights: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> tables: array<u32>;
@group(0) @binding(4) var<storage, read> chunk0: array<u32>;
@group(0) @binding(5) var<storage, read> chunk1: array<u32>;
@group(0) @binding(6) var<storage, read> chunk2: array<u32>;
@group(0) @binding(7) var<storage, read> chunk3: array<u32>;

// BATCH, the entries per batch, is defined by the pipeline (tiles.rs's ENTRY_BATCH); with
// the node accumulators, the batch arrays stay within WebGPU's default 16 KiB of workgroup
// memory.

// Bit of a batch entry's flags word: its weight is not zero, so it is added.
const TO_ADD: u32 = 0x80000000u;

// The tile's lattice entries summed: per segment, per lattice node, RGB.
var<workgroup> nodes: array<f32, NODE_FLOATS>;
// The current batch of the tile's entries: per entry weight · scale (3 floats), and its
// flags (`Entry` packing, plus TO_ADD), first sample and segment mask (3 words).
var<workgroup> batch_ws: array<f32, 3u * BATCH>;
var<workgroup> batch_entry: array<u32, 3u * BATCH>;
// Whether the tile has a lattice entry to add (zero at the start of every workgroup).
var<workgroup> lattice_any: atomic<u32>;
// Most groups of invocations that sum a tile's lattice entries side by side.
const MAX_LANES: u32 = 8u;

// Where a tile's lattice block (lattice.rs) keeps each part, in words of `tables`.
struct Lattice {
    step: u32,
    segments: u32,
    nx: u32,
    ny: u32,
    map_at: u32,
    counts_at: u32,
    sets_at: u32,
    set_words: u32,
    masks_at: u32,
}

fn lattice_of(block: u32, pixels: u32) -> Lattice {
    let head = tables[block];
    let segments = (head >> 8u) & 0xffu;
    let nx = (head >> 16u) & 0xffu;
    let ny = head >> 24u;
    let map_at = block + 1u;
    let counts_at = map_at + (pixels + 3u) / 4u;
    let sets_at = counts_at + segments;
    let set_words = (nx * ny + 31u) / 32u;
    return Lattice(
        head & 0xffu,
        segments,
        nx,
        ny,
        map_at,
        counts_at,
        sets_at,
        set_words,
        sets_at + segments * set_words,
    );
}

// The two nodes along one axis of coordinate `x` and their weights, as lattice.rs's
// axis_hats: cell min(x / step, n − 2), weights 1 − t and t.
struct Hats {
    i0: u32,
    i1: u32,
    w0: f32,
    w1: f32,
}

fn axis_hats(x: u32, step: u32, n: u32) -> Hats {
    if n <= 1u {
        return Hats(0u, 0u, 1.0, 0.0);
    }
    let i = min(x / step, n - 2u);
    let t = f32(x - i * step) / f32(step);
    return Hats(i, i + 1u, 1.0 - t, t);
}

// Node slot `j` of a tile's lattice: its segment, its channel, whether the segment stores
// its node, and the node's place among those the segment stores.
struct Slot {
    segment: u32,
    channel: u32,
    stored: bool,
    index: u32,
}

fn slot_of(l: Lattice, j: u32) -> Slot {
    let per_segment = 3u * l.nx * l.ny;
    let s = j / per_segment;
    let node = (j % per_segment) / 3u;
    let node_set = l.sets_at + s * l.set_words;
    let bits = tables[node_set + node / 32u];
    let bit = node % 32u;
    var index = countOneBits(bits & ((1u << bit) - 1u));
    for (var q = 0u; q < node / 32u; q++) {
        index += countOneBits(tables[node_set + q]);
    }
    return Slot(s, j % 3u, ((bits >> bit) & 1u) == 1u, index);
}

// Where slot `slot`'s coefficient of a lattice entry with values from `offset`, `channels`
// channels and segment mask `mask` lies: after the coefficients of the covered segments
// below the slot's (covered segments in id order).
fn coefficient_at(l: Lattice, slot: Slot, mask: u32, offset: u32, channels: u32) -> u32 {
    var start = 0u;
    var below = mask & ((1u << slot.segment) - 1u);
    while below != 0u {
        start += tables[l.counts_at + firstTrailingBit(below)];
        below &= below - 1u;
    }
    return offset + (start + slot.index) * channels + select(slot.channel, 0u, channels == 1u);
}

// Adds `ws ·` a lattice entry (values from `offset` in chunk `chunk`, `channels` channels,
// covering the segments of `mask`) into the node slots this invocation owns beyond its
// first (lid + INVOCATIONS, …: only in tiles of more than INVOCATIONS node floats).
fn accumulate_more(
    l: Lattice, mask: u32, offset: u32, channels: u32, chunk: u32, ws: vec3<f32>, lid: u32,
    floats: u32,
) {
    for (var j = lid + INVOCATIONS; j < floats; j += INVOCATIONS) {
        let slot = slot_of(l, j);
        if ((mask >> slot.segment) & 1u) == 0u || !slot.stored {
            continue;
        }
        let at = coefficient_at(l, slot, mask, offset, channels);
        nodes[j] = nodes[j] + ws[slot.channel] * sample(chunk, at);
    }
}

fn node(n: u32) -> vec3<f32> {
    return vec3<f32>(nodes[3u * n], nodes[3u * n + 1u], nodes[3u * n + 2u]);
}

// Pixel (x, y)'s share of the tile's node accumulators: its segment's ≤ 4 hat nodes, in
// lattice.rs's expand order (node rows outer, columns inner).
fn expand(l: Lattice, x: u32, y: u32, i: u32) -> vec3<f32> {
    let segment = (tables[l.map_at + i / 4u] >> (8u * (i % 4u))) & 0xffu;
    let hx = axis_hats(x, l.step, l.nx);
    let hy = axis_hats(y, l.step, l.ny);
    let row0 = segment * l.nx * l.ny + hy.i0 * l.nx;
    let row1 = segment * l.nx * l.ny + hy.i1 * l.nx;
    var sum = vec3<f32>(0.0);
    sum = sum + (hx.w0 * hy.w0) * node(row0 + hx.i0);
    sum = sum + (hx.w1 * hy.w0) * node(row0 + hx.i1);
    sum = sum + (hx.w0 * hy.w1) * node(row1 + hx.i0);
    sum = sum + (hx.w1 * hy.w1) * node(row1 + hx.i1);
    return sum;
}

fn entry(k: u32) -> Entry {
    let at = params.entries_at + 4u * k;
    return Entry(tables[at], tables[at + 1u], bitcast<f32>(tables[at + 2u]), tables[at + 3u]);
}

// An entry's channels (1 grey, 3 RGB).
fn channels_of(flags: u32) -> u32 {
    return flags & 0xffu;
}

// An entry's kind: KIND_LATTICE, or 0 for one value per pixel and channel.
fn kind_of(flags: u32) -> u32 {
    return (flags >> 8u) & 0xffu;
}

// Which chunk binding of the group holds an entry's values (0..3).
fn chunk_of(flags: u32) -> u32 {
    return (flags >> 16u) & 0xffu;
}

// The slot is the same for every invocation of a workgroup at a given entry, so the
// switch does not diverge.
fn word(slot: u32, i: u32) -> u32 {
    switch slot {
        case 0u: { return chunk0[i]; }
        case 1u: { return chunk1[i]; }
        case 2u: { return chunk2[i]; }
        default: { return chunk3[i]; }
    }
}

// IEEE binary16 → f32, exactly, subnormals included. Done by hand rather than with
// unpack2x16float, whose handling of f16 subnormals the drivers may flush to zero; the
// values are finite (the stack is validated), so infinities and NaNs need no case.
fn half_to_f32(h: u32) -> f32 {
    let sign = (h & 0x8000u) << 16u;
    let exponent = (h >> 10u) & 0x1fu;
    let mantissa = h & 0x3ffu;
    if exponent == 0u {
        // 0 or subnormal: mantissa · 2⁻²⁴ (0x33800000), exact in f32.
        let magnitude = f32(mantissa) * bitcast<f32>(0x33800000u);
        return bitcast<f32>(bitcast<u32>(magnitude) | sign);
    }
    return bitcast<f32>(sign | ((exponent + 112u) << 23u) | (mantissa << 13u));
}

// Sample `i` of chunk `slot`.
fn sample(slot: u32, i: u32) -> f32 {
    if params.format == 1u {
        return bitcast<f32>(word(slot, i));
    }
    let w = word(slot, i >> 1u);
    return half_to_f32(select(w & 0xffffu, w >> 16u, (i & 1u) == 1u));
}

// Loads entries base .. base + count of the tile (whose first entry is `first`) into the
// batch arrays, one per invocation, and notes in `lattice_any` a lattice entry to add.
fn load_batch(base: u32, count: u32, first: u32, l: Lattice, lid: u32) {
    if lid >= count {
        return;
    }
    let k = base + lid;
    let e = entry(k);
    let w = weights[e.layer].xyz;
    let ws = w * e.scale;
    batch_ws[3u * lid] = ws.x;
    batch_ws[3u * lid + 1u] = ws.y;
    batch_ws[3u * lid + 2u] = ws.z;
    let to_add = any(w != vec3<f32>(0.0));
    batch_entry[3u * lid] = e.flags | select(0u, TO_ADD, to_add);
    batch_entry[3u * lid + 1u] = e.offset;
    var mask = 0u;
    if kind_of(e.flags) == KIND_LATTICE {
        mask = tables[l.masks_at + (k - first)];
        if to_add {
            atomicOr(&lattice_any, 1u);
        }
    }
    batch_entry[3u * lid + 2u] = mask;
}

// Weight · scale of entry `e` of the batch.
fn batch_weight(e: u32) -> vec3<f32> {
    return vec3<f32>(batch_ws[3u * e], batch_ws[3u * e + 1u], batch_ws[3u * e + 2u]);
}

@compute @workgroup_size(16, 16)
fn main(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_id) local: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
) {
    // Dispatches wider than the per-dimension limit fold into rows of `groups.x` tiles.
    let t = group.x + group.y * groups.x;
    // Uniform across the workgroup: whole workgroups leave, never part of one.
    if t >= params.tile_count {
        return;
    }
    let tile = params.first_tile + t;
    let x0 = (tile % params.tiles_x) * TILE;
    let y0 = (tile / params.tiles_x) * TILE;
    let tile_width = min(TILE, params.width - x0);
    let tile_height = min(TILE, params.height - y0);
    // Invocations outside an edge tile run the loop without reading or writing their pixel,
    // so that the workgroup stays in uniform control flow: they still own node slots of the
    // lattice entries, and every invocation reaches the barrier before the expansion.
    let inside = local.x < tile_width && local.y < tile_height;
    // The pixel's index among the tile's values (the tile's own width, row-major).
    let i = local.y * tile_width + local.x;
    var grey = vec3<f32>(0.0);
    var rgb = vec3<f32>(0.0);
    var added = false;
    // The lattice pointers follow the entry records, whose count is the last tile start.
    let lattices_at = params.entries_at + 4u * tables[params.entries_at - 1u];
    let block = tables[lattices_at + tile];
    var l: Lattice;
    var node_floats = 0u;
    // The node slot this invocation sums in `own_sum` (see the lattice entries' loop).
    var own = Slot(0u, 0u, false, 0u);
    var own_sum = 0.0;
    if block != 0u {
        l = lattice_of(block, tile_width * tile_height);
        node_floats = 3u * l.segments * l.nx * l.ny;
        for (var j = lid + INVOCATIONS; j < node_floats; j += INVOCATIONS) {
            nodes[j] = 0.0;
        }
    }
    let first = tables[tile];
    let end = tables[tile + 1u];
    // The tile's per-pixel entries come first, then its lattice entries (tiles.rs); the
    // block's last word counts the former.
    var lattice_first = end;
    if block != 0u {
        lattice_first = first + tables[l.masks_at + (end - first)];
    }
    // Per-pixel entries: each invocation adds every one at its own pixel.
    for (var base = first; base < lattice_first; base += BATCH) {
        let count = min(BATCH, lattice_first - base);
        load_batch(base, count, first, l, lid);
        workgroupBarrier();
        for (var e = 0u; e < count; e++) {
            let flags = batch_entry[3u * e];
            if (flags & TO_ADD) == 0u {
                continue;
            }
            added = true;
            if !inside {
                continue;
            }
            let chunk = chunk_of(flags);
            let offset = batch_entry[3u * e + 1u];
            let ws = batch_weight(e);
            if channels_of(flags) == 1u {
                grey = fma(ws, vec3<f32>(sample(chunk, offset + i)), grey);
            } else {
                let j = offset + 3u * i;
                let values = vec3<f32>(
                    sample(chunk, j),
                    sample(chunk, j + 1u),
                    sample(chunk, j + 2u),
                );
                rgb = fma(ws, values, rgb);
            }
        }
        // The batch is read by every invocation before the next one overwrites it.
        workgroupBarrier();
    }
    // Lattice entries. Where the tile's node slots fill at most half the workgroup, the
    // invocations form `lanes` groups of one invocation per slot, and group k sums the
    // batch's entries k, k + lanes, …; the groups' sums are added per slot at the end, in
    // group order. Otherwise one group: invocation lid sums slot lid (and, through
    // accumulate_more, lid + INVOCATIONS, …) over every entry.
    var lanes = 1u;
    var lane = 0u;
    if node_floats > 0u && node_floats <= INVOCATIONS / 2u {
        lanes = min(MAX_LANES, INVOCATIONS / node_floats);
        lane = lid / node_floats;
    }
    if block != 0u && lane < lanes && lid - lane * node_floats < node_floats {
        own = slot_of(l, lid - lane * node_floats);
    }
    for (var base = lattice_first; base < end; base += BATCH) {
        let count = min(BATCH, end - base);
        load_batch(base, count, first, l, lid);
        workgroupBarrier();
        if lanes == 1u {
            for (var e = 0u; e < count; e++) {
                let flags = batch_entry[3u * e];
                if (flags & TO_ADD) == 0u {
                    continue;
                }
                let channels = channels_of(flags);
                let chunk = chunk_of(flags);
                let offset = batch_entry[3u * e + 1u];
                let mask = batch_entry[3u * e + 2u];
                let ws = batch_weight(e);
                if own.stored && ((mask >> own.segment) & 1u) == 1u {
                    let at = coefficient_at(l, own, mask, offset, channels);
                    own_sum = own_sum + ws[own.channel] * sample(chunk, at);
                }
                accumulate_more(l, mask, offset, channels, chunk, ws, lid, node_floats);
            }
        } else if own.stored {
            for (var e = lane; e < count; e += lanes) {
                let flags = batch_entry[3u * e];
                let mask = batch_entry[3u * e + 2u];
                if (flags & TO_ADD) == 0u || ((mask >> own.segment) & 1u) == 0u {
                    continue;
                }
                let at = coefficient_at(l, own, mask, batch_entry[3u * e + 1u], channels_of(flags));
                let v = sample(chunk_of(flags), at);
                own_sum = own_sum + batch_ws[3u * e + own.channel] * v;
            }
        }
        workgroupBarrier();
    }
    let lattice_added = atomicLoad(&lattice_any) != 0u;
    added = added || lattice_added;
    if block != 0u {
        // The groups' sums, added per slot in group order (one group: the sum itself).
        if lane < lanes {
            batch_ws[lid] = own_sum;
        }
        workgroupBarrier();
        if lid < node_floats {
            var sum = batch_ws[lid];
            for (var k = 1u; k < lanes; k++) {
                sum = sum + batch_ws[k * node_floats + lid];
            }
            nodes[lid] = sum;
        }
        // Every slot's sum is complete before any pixel reads it.
        workgroupBarrier();
    }
    if lattice_added && inside {
        rgb = rgb + expand(l, local.x, local.y, i);
    }
    if !inside {
        return;
    }
    let p = (y0 + local.y) * params.width + x0 + local.x;
    if params.reset == 1u {
        image[p] = vec4<f32>(grey + rgb, 1.0);
    } else if added {
        image[p] = vec4<f32>(image[p].xyz + (grey + rgb), 1.0);
    }
}
