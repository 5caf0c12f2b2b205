//! [`GpuMemory`]: the bytes the GPU relighter allocated on the device, by purpose — the
//! figure issue 14 asks to equal the stack's size plus the image and the weights.

/// Bytes of the GPU relighter's buffers, as created (wgpu sizes buffers in whole words).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GpuMemory {
    /// The stack's values in their precision: its sample bytes, plus at most 2 bytes of
    /// padding per chunk (a chunk ends on a whole word).
    pub values: u64,
    /// Tile starts and lattice pointers (8 bytes a tile), entry records (16 bytes an
    /// entry) and the lattice blocks of the tiles that have one.
    pub tables: u64,
    /// The RGBA f32 image (16 bytes a pixel).
    pub image: u64,
    /// The per-layer weights written per relight (16 bytes a layer).
    pub weights: u64,
    /// The mappable copy of the image the host reads back (host-visible memory; on a
    /// discrete GPU it lives in system memory).
    pub readback: u64,
    /// Parameter blocks, the placeholder bound to unused chunk slots, timestamp queries.
    pub other: u64,
}

impl GpuMemory {
    /// The stack on the GPU: values and tables.
    pub fn stack(&self) -> u64 {
        self.values + self.tables
    }

    /// Everything.
    pub fn total(&self) -> u64 {
        self.values + self.tables + self.image + self.weights + self.readback + self.other
    }
}
