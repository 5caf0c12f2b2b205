//! The fit table's grid: its roughness rows, the targets' base colours and F0, and the row
//! type the generated table is made of.

/// Roughness of the table's rows.
pub const ROUGHNESS: [f32; 20] = [
    0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6, 0.65, 0.7, 0.75, 0.8, 0.85,
    0.9, 0.95, 1.0,
];
/// Base colours of the metal targets.
pub const METAL_BASE: [f32; 5] = [0.0, 0.25, 0.5, 0.75, 1.0];
/// Specular F0 of the dielectric targets (0.04 is IOR 1.5 at Specular IOR Level 0.5).
pub const DIELECTRIC_F0: [f32; 11] = [
    0.0, 0.01, 0.02, 0.04, 0.06, 0.08, 0.12, 0.16, 0.25, 0.5, 1.0,
];

/// One roughness row: the fitted exponent, `[Kd, Ks]` per metal base colour and, per
/// dielectric F0, `[Kd, Ks]` at base colour 0 and at base colour 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    pub ns: f32,
    pub metal: [[f32; 2]; 5],
    pub dielectric: [[[f32; 2]; 2]; 11],
}
