//! The features' type: per pixel its normal, the fixed surfaces' albedo and the editable
//! regions' shares (the module doc of [`super`] says why these).

/// One editable region's part of one pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EditableShare {
    /// The region's position among the editable regions (the order of the stack's header).
    pub region: u16,
    /// The share of the pixel's samples that hit it, in (0, 1].
    pub coverage: f32,
    /// The sum over those samples of its albedo texture (1 where it has none), divided by
    /// the pixel's sample count: what the diffuse colour is multiplied by.
    pub texture: [f32; 3],
}

/// The auxiliary features of one image: see the module doc.
#[derive(Clone, Debug, PartialEq)]
pub struct PixelFeatures {
    pub(super) width: u32,
    pub(super) height: u32,
    /// Per pixel (row-major, top row first), the mean shading normal of its samples (world
    /// space, facing the camera; samples that hit nothing count as 0), RGB-interleaved.
    pub(super) normal: Vec<f32>,
    /// Per pixel, the albedo the fixed (non-editable) surfaces add: Σ over the samples that
    /// hit one of its albedo, divided by the sample count.
    pub(super) fixed_albedo: Vec<f32>,
    /// Per pixel, where its shares start in `shares`; one more entry than pixels.
    pub(super) starts: Vec<u32>,
    pub(super) shares: Vec<EditableShare>,
    /// Number of editable regions of the scene.
    pub(super) editable_regions: usize,
}

impl PixelFeatures {
    /// Width and height in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The normal image: RGB per pixel, values in [−1, 1].
    pub fn normal(&self) -> &[f32] {
        &self.normal
    }

    /// Number of editable regions the features were traced for.
    pub fn editable_regions(&self) -> usize {
        self.editable_regions
    }

    /// The editable regions' shares of pixel `index` (row-major).
    pub fn shares(&self, index: usize) -> &[EditableShare] {
        let (a, b) = (self.starts[index] as usize, self.starts[index + 1] as usize);
        &self.shares[a..b]
    }
}
