// The relight sum on the GPU over the tiled stack: image = Σ weight · scale · value, one
// workgroup per 16×16 tile and one invocation per pixel. See kernel.rs for the host side,
// tiles.rs for the tables and layout.rs for the value chunks.
//
// Per pixel the order of operations is the CPU tiled sum's (core/engine/src/relight/
// tiled_sum.rs): the tile's entries in layer order, grey entries into one accumulator and
// RGB entries into another, each `acc = fma(weight · scale, value, acc)`, then
// `pixel = (grey + rgb)` on a full relight or `pixel += (grey + rgb)` on an incremental one.
// The accumulators live in registers: the image is read at most once and written once.
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
    channels: u32,
    // 0: one value per pixel and channel. Another kind (e.g. a per-tile lattice of
    // coefficients) adds a case in `main`'s switch.
    kind: u32,
    // Which chunk binding of the group holds the values (0..3).
    slot: u32,
    scale: f32,
    // First sample of the entry in its chunk.
    offset: u32,
}

const TILE: u32 = 16u;
const KIND_VALUES: u32 = 0u;

@group(0) @binding(0) var<storage, read_write> image: array<vec4<f32>>;
@group(0) @binding(1) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> weights: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> tables: array<u32>;
@group(0) @binding(4) var<storage, read> chunk0: array<u32>;
@group(0) @binding(5) var<storage, read> chunk1: array<u32>;
@group(0) @binding(6) var<storage, read> chunk2: array<u32>;
@group(0) @binding(7) var<storage, read> chunk3: array<u32>;

fn entry(k: u32) -> Entry {
    let at = params.entries_at + 4u * k;
    let flags = tables[at + 1u];
    return Entry(
        tables[at],
        flags & 0xffu,
        (flags >> 8u) & 0xffu,
        (flags >> 16u) & 0xffu,
        bitcast<f32>(tables[at + 2u]),
        tables[at + 3u],
    );
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

@compute @workgroup_size(16, 16)
fn main(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_id) local: vec3<u32>,
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
    // Invocations outside an edge tile run the loop without reading or writing, so that the
    // workgroup stays in uniform control flow (a kind that shares work across the tile
    // through workgroup memory needs barriers in the loop).
    let inside = local.x < tile_width && local.y < tile_height;
    // The pixel's index among the tile's values (the tile's own width, row-major).
    let i = local.y * tile_width + local.x;
    var grey = vec3<f32>(0.0);
    var rgb = vec3<f32>(0.0);
    var added = false;
    let end = tables[tile + 1u];
    for (var k = tables[tile]; k < end; k++) {
        let e = entry(k);
        let w = weights[e.layer].xyz;
        if all(w == vec3<f32>(0.0)) {
            continue;
        }
        added = true;
        let ws = w * e.scale;
        switch e.kind {
            case KIND_VALUES: {
                if inside {
                    if e.channels == 1u {
                        grey = fma(ws, vec3<f32>(sample(e.slot, e.offset + i)), grey);
                    } else {
                        let j = e.offset + 3u * i;
                        let v = vec3<f32>(
                            sample(e.slot, j),
                            sample(e.slot, j + 1u),
                            sample(e.slot, j + 2u),
                        );
                        rgb = fma(ws, v, rgb);
                    }
                }
            }
            default: {}
        }
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
