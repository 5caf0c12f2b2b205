// The relight sum on the GPU: image = Σ weight · layer over a list of layers, one
// invocation per pixel. See kernel.rs for the host side and layout.rs for the packing.
//
// One dispatch per bind group (4 chunks of layers). A full relight resets the image in the
// first dispatch (`reset` = 1) and adds in the others; an incremental edit adds
// (w_new − w_old) · layer for the edited region's layers only, on top of the image kept
// on the GPU. The accumulator lives in registers: the image is read at most once and
// written once per dispatch, whatever the number of layers.

// One layer to add. 32 bytes, std430-aligned to 16.
struct Entry {
    // Weight × light tint × layer scale, per RGB channel.
    weight: vec3<f32>,
    // First word of the layer's tile mask in `masks` (tiles.rs): bit t set when tile t,
    // the pixels of workgroup t, holds a non-zero sample.
    mask: u32,
    // Which chunk binding holds the layer (0..3).
    chunk: u32,
    // First 32-bit word of the layer in its chunk.
    offset: u32,
    // 1: grey (one sample per pixel, added to R, G and B); 3: RGB interleaved.
    channels: u32,
    // 0: two f16 per word, low half first; 1: one f32 per word.
    format: u32,
}

struct Params {
    pixels: u32,
    // Entries of this dispatch: entries[first .. first + count].
    first: u32,
    count: u32,
    // 1: start from black; 0: add to the current image.
    reset: u32,
}

const WORKGROUP: u32 = 256u;

@group(0) @binding(0) var<storage, read_write> image: array<vec4<f32>>;
@group(0) @binding(1) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> entries: array<Entry>;
@group(0) @binding(3) var<storage, read> chunk0: array<u32>;
@group(0) @binding(4) var<storage, read> chunk1: array<u32>;
@group(0) @binding(5) var<storage, read> chunk2: array<u32>;
@group(0) @binding(6) var<storage, read> chunk3: array<u32>;
@group(0) @binding(7) var<storage, read> masks: array<u32>;

// The chunk index is the same for every invocation of a dispatch at a given entry, so the
// switch does not diverge.
fn word(chunk: u32, i: u32) -> u32 {
    switch chunk {
        case 0u: { return chunk0[i]; }
        case 1u: { return chunk1[i]; }
        case 2u: { return chunk2[i]; }
        default: { return chunk3[i]; }
    }
}

// Sample `i` of the layer described by `e` (index among the layer's values).
fn sample(e: Entry, i: u32) -> f32 {
    if e.format == 1u {
        return bitcast<f32>(word(e.chunk, e.offset + i));
    }
    let pair = unpack2x16float(word(e.chunk, e.offset + (i >> 1u)));
    return select(pair.x, pair.y, (i & 1u) == 1u);
}

@compute @workgroup_size(256)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    // Dispatches wider than 65535 workgroups fold into rows of `groups.x` workgroups.
    let p = gid.x + gid.y * groups.x * WORKGROUP;
    if p >= params.pixels {
        return;
    }
    var acc = vec3<f32>(0.0);
    if params.reset == 0u {
        acc = image[p].xyz;
    }
    // The tile is the workgroup, so the skip below is uniform across it.
    let tile = p / WORKGROUP;
    let end = params.first + params.count;
    for (var k = params.first; k < end; k++) {
        let e = entries[k];
        if ((masks[e.mask + (tile >> 5u)] >> (tile & 31u)) & 1u) == 0u {
            continue;
        }
        if e.channels == 1u {
            acc += e.weight.xyz * sample(e, p);
        } else {
            let i = 3u * p;
            acc += e.weight.xyz * vec3<f32>(sample(e, i), sample(e, i + 1u), sample(e, i + 2u));
        }
    }
    image[p] = vec4<f32>(acc, 1.0);
}
