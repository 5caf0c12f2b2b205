//! Guided indirect sampling: a short first pass records where indirect light comes from,
//! per screen tile, and the bake then draws its indirect directions partly from that record.
//!
//! For [`guide_samples`] cosine-distributed indirect rays per pixel, the pass records the
//! direction and the luminance of the light that comes back along it (direct light reflected
//! at the secondary hit by the bake-time materials, i.e. exactly what the bake's indirect
//! estimator carries) times the cosine at the eye hit, over the cosine pdf: an estimate of
//! `L(ω)·cos θ`, the diffuse part of the integrand. The samples of a tile of [`guide_tile`]²
//! pixels build one [`DirectionTree`]: an adaptive quadtree over the sphere, fine where the
//! light is concentrated (a caustic, the bright patch under a lamp), sampled by hierarchical
//! sample warping with an exact pdf.
//!
//! In the bake ([`IndirectSampling::Guided`](crate::bake::settings::IndirectSampling)) the indirect
//! direction comes from a defensive one-sample mixture: [`GUIDE_WEIGHT`] of the tile's tree,
//! the rest the region's cosine-and-lobes [`super::mixture::DirectionMixture`]. The pdf of the
//! whole mixture is evaluated for every direction, so the estimate is unbiased whatever the
//! tree holds (a tile that saw no light, or a tree that points below a surface, only wastes
//! samples), and one sample set still serves all layers, so their noise stays correlated.
//! The tree is built from the bake-time materials: editing a region's material afterwards
//! leaves the guide slightly off for the new material — still unbiased, a little noisier.
//!
//! This file holds the guide itself; the pass that builds it is
//! [`crate::bake::prepare::guide_pass`].
//!
//! The pass is deterministic (one task per tile, pixels in order, its own random stream), so
//! a reference render with the same settings builds the same guide and traces the same paths
//! as the bake.

use crate::bake::path::guide_tree::DirectionTree;
use crate::bake::settings::BakeSettings;

/// Fewest guide paths per pixel (3 rays each: eye, indirect, one shadow ray per light).
pub const MIN_GUIDE_SAMPLES: u32 = 4;
/// Most guide paths per pixel.
pub const MAX_GUIDE_SAMPLES: u32 = 32;

/// Guide paths per pixel for `settings`: a quarter of the bake's indirect paths
/// (spp × indirect samples / 4), clamped to [[`MIN_GUIDE_SAMPLES`], [`MAX_GUIDE_SAMPLES`]].
/// A fixed share keeps the pass a small part of every bake's rays, while a bigger bake, whose
/// indirect noise is lower, gets a finer guide; more paths resolve more of a concentrated
/// light (docs/measurements.md, "Sampling", has the measured trade-off).
pub fn guide_samples(settings: &BakeSettings) -> u32 {
    (settings.spp.saturating_mul(settings.indirect_samples) / 4)
        .clamp(MIN_GUIDE_SAMPLES, MAX_GUIDE_SAMPLES)
}

/// Side of a guide tile, pixels, for `samples` guide paths a pixel: 8 with ≥ 16 paths, else
/// 16, so that a tile gathers about a thousand paths. Locality is what pays, as long as the
/// paths fill the trees: small tiles need many paths (docs/measurements.md, "Sampling").
pub fn guide_tile(samples: u32) -> u32 {
    if samples >= 16 {
        8
    } else {
        16
    }
}

/// Share of the indirect mixture drawn from the guide (the rest is cosine and lobes, which
/// bound the weight where the guide is wrong).
pub const GUIDE_WEIGHT: f32 = 0.5;

/// The guide trees of every tile of an image, ready for sampling.
#[derive(Clone, Debug)]
pub struct GuideField {
    /// Tile side, pixels ([`guide_tile`]).
    pub(in crate::bake) side: u32,
    pub(in crate::bake) tiles_x: u32,
    pub(in crate::bake) tiles_y: u32,
    pub(in crate::bake) trees: Vec<Option<DirectionTree>>,
    /// Rays the guide pass traced.
    pub rays: u64,
    /// Wall time of the guide pass, seconds.
    pub seconds: f64,
}

impl GuideField {
    /// The tree of the tile holding pixel (`px`, `py`); `None` where the pass saw no
    /// indirect light there.
    #[inline]
    pub fn sampler(&self, px: u32, py: u32) -> Option<&DirectionTree> {
        let (tx, ty) = (px / self.side, py / self.side);
        if tx >= self.tiles_x || ty >= self.tiles_y {
            return None;
        }
        self.trees[(ty * self.tiles_x + tx) as usize].as_ref()
    }

    /// Tile side, tiles across and down, and the trees (row-major): what a guide file
    /// stores ([`crate::bake::farm::guide_file`]).
    pub fn parts(&self) -> (u32, u32, u32, &[Option<DirectionTree>]) {
        (self.side, self.tiles_x, self.tiles_y, &self.trees)
    }

    /// A field from [`Self::parts`] (read back from a guide file); `None` when the tree count
    /// is not tiles across × down.
    pub fn from_parts(
        side: u32,
        tiles_x: u32,
        tiles_y: u32,
        trees: Vec<Option<DirectionTree>>,
        rays: u64,
        seconds: f64,
    ) -> Option<GuideField> {
        (side > 0 && trees.len() as u64 == tiles_x as u64 * tiles_y as u64).then_some(GuideField {
            side,
            tiles_x,
            tiles_y,
            trees,
            rays,
            seconds,
        })
    }

    /// Tile side, pixels.
    pub fn tile_side(&self) -> u32 {
        self.side
    }

    /// Tiles with a usable tree, of all tiles.
    pub fn coverage(&self) -> (usize, usize) {
        (
            self.trees.iter().filter(|s| s.is_some()).count(),
            self.trees.len(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pass_grows_with_the_bake_and_the_tiles_shrink_with_it() {
        let at = |spp, indirect| BakeSettings {
            spp,
            indirect_samples: indirect,
            ..Default::default()
        };
        assert_eq!(guide_samples(&at(4, 2)), MIN_GUIDE_SAMPLES);
        assert_eq!(guide_samples(&at(16, 1)), 4);
        assert_eq!(guide_samples(&at(16, 4)), 16);
        assert_eq!(guide_samples(&at(128, 2)), MAX_GUIDE_SAMPLES);
        assert_eq!(guide_samples(&at(u32::MAX, u32::MAX)), MAX_GUIDE_SAMPLES);
        assert_eq!((guide_tile(4), guide_tile(16), guide_tile(32)), (16, 8, 8));
    }
}
