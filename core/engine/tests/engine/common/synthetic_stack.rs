//! Synthetic transfer stacks for the relight tests: random layers, any mix of precision,
//! channels and path signatures, built by hand (no bake involved).

use relume_engine::layer_key::{LayerKey, PathVertex};
use relume_engine::stack::{Layer, LayerSamples, Precision, StackHeader, TransferStack};
use relume_engine::Rgb;

use super::stack_header::{blinn_phong_region, stack_header};

/// xorshift64*: deterministic, dependency-free randomness for tests.
pub struct Rng(u64);
impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
}

/// Regions: editable "Bunny" (editable 0), fixed "Walls", editable "Floor" (editable 1).
pub fn header(width: u32, height: u32) -> StackHeader {
    let region =
        |name: &str, editable| blinn_phong_region(name, editable, [0.5; 3], [0.2; 3], 20.0);
    StackHeader {
        spp: 16,
        seed: 1,
        scene_hash: "test".into(),
        ..stack_header(
            width,
            height,
            vec![
                region("Bunny", true),
                region("Walls", false),
                region("Floor", true),
            ],
        )
    }
}

pub fn e(region: u16, basis: u16) -> PathVertex {
    PathVertex::Editable { region, basis }
}

/// The keys of a one-bounce stack with two editable regions of `nb` bases and the fixed
/// region: World, direct (eye vertex), and every (eye, bounce) pair.
pub fn one_bounce_keys(nb: u16) -> Vec<LayerKey> {
    let mut verts = vec![PathVertex::Fixed];
    for r in 0..2 {
        for b in 0..nb {
            verts.push(e(r, b));
        }
    }
    let mut keys = vec![LayerKey::new(vec![])];
    for &v in &verts {
        keys.push(LayerKey::new(vec![v]));
    }
    for &v0 in &verts {
        for &v1 in &verts {
            keys.push(LayerKey::new(vec![v0, v1]));
        }
    }
    keys
}

/// A random layer: values in [−1, 4) (basis layers can be negative), with the rows in
/// `zero_rows` and the columns `x < zero_left` all zero.
#[allow(clippy::too_many_arguments)]
pub fn random_layer(
    rng: &mut Rng,
    key: LayerKey,
    width: usize,
    height: usize,
    channels: u32,
    precision: Precision,
    zero_rows: std::ops::Range<usize>,
    zero_left: usize,
) -> Layer {
    let ch = channels as usize;
    let mut v = vec![0.0f32; width * height * ch];
    for y in 0..height {
        if zero_rows.contains(&y) {
            continue;
        }
        for x in zero_left..width {
            for c in 0..ch {
                v[(y * width + x) * ch + c] = rng.range(-1.0, 4.0);
            }
        }
    }
    Layer::from_f32(key, channels, &v, precision)
}

/// Naive reference: Σ weight · layer in f64, RGB per pixel, weight computed here from the
/// path independently of the engine.
pub fn reference(stack: &TransferStack, coefs: &[Vec<Rgb>]) -> Vec<[f64; 3]> {
    let (w, h) = (stack.header.width as usize, stack.header.height as usize);
    let mut out = vec![[0.0f64; 3]; w * h];
    for layer in &stack.layers {
        let mut wt = [1.0f64; 3];
        for v in &layer.key.path {
            if let PathVertex::Editable { region, basis }
            | PathVertex::Subsurface { region, basis } = v
            {
                let c = coefs[*region as usize][*basis as usize];
                wt[0] *= c.x as f64;
                wt[1] *= c.y as f64;
                wt[2] *= c.z as f64;
            }
        }
        let ch = layer.channels as usize;
        for (p, o) in out.iter_mut().enumerate() {
            for c in 0..3 {
                let i = p * ch + if ch == 1 { 0 } else { c };
                let s = match &layer.samples {
                    LayerSamples::F16(v) => v[i].to_f64(),
                    LayerSamples::F32(v) => v[i] as f64,
                };
                o[c] += wt[c] * s * layer.scale as f64;
            }
        }
    }
    out
}

/// Largest |got − ref| over the image divided by the largest Σ|terms| bound, checked against
/// `tol`; also checks that alpha is exactly 1.
pub fn assert_close(got: &[f32], reference: &[[f64; 3]], tol: f64, what: &str) {
    assert_eq!(got.len(), reference.len() * 4, "{what}: image size");
    let scale = reference
        .iter()
        .flat_map(|p| p.iter())
        .fold(1.0f64, |m, v| m.max(v.abs()));
    for (p, r) in reference.iter().enumerate() {
        assert_eq!(got[4 * p + 3], 1.0, "{what}: alpha of pixel {p}");
        for c in 0..3 {
            let d = (got[4 * p + c] as f64 - r[c]).abs();
            assert!(
                d <= tol * scale,
                "{what}: pixel {p} channel {c}: {} vs {} (|d| = {d:e}, scale {scale})",
                got[4 * p + c],
                r[c]
            );
        }
    }
}

/// Random coefficients (RGB in [−0.5, 1.5)) for every editable region.
pub fn random_coefs(rng: &mut Rng, counts: &[usize]) -> Vec<Vec<Rgb>> {
    counts
        .iter()
        .map(|&n| {
            (0..n)
                .map(|_| {
                    Rgb::new(
                        rng.range(-0.5, 1.5),
                        rng.range(-0.5, 1.5),
                        rng.range(-0.5, 1.5),
                    )
                })
                .collect()
        })
        .collect()
}
