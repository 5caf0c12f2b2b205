//! Path signatures: the key of every layer of a transfer stack, shared by the bake, the stack
//! file and the relight (a leaf: it imports nothing of theirs).
//!
//! A layer holds the radiance of all light paths that met the same sequence of
//! (region, basis) pairs, listed from the eye towards the light. Its relight weight is the
//! product of the coefficients along that sequence, so the key is a general list, not a
//! fixed table: direct light has one vertex, one bounce two, and more bounces or light
//! groups fit without a new format.

use std::fmt::Write as _;

/// One scattering vertex of a path signature.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum PathVertex {
    /// The fixed region R̂, whose whole BRDF ρ̂ was baked in (coefficient 1).
    Fixed,
    /// Editable region number `region` (its position among the editable regions),
    /// basis function number `basis` (0 = diffuse).
    Editable { region: u16, basis: u16 },
    /// Subsurface light of translucent editable region `region` leaving at the eye through
    /// subsurface basis function `B_k`; `basis` is the region's coefficient slot (after its
    /// BRDF and eye-diffuse slots, see [`crate::bssrdf::coefficients`]), so relight weights
    /// index the region's coefficients alike for both kinds of vertex. Named `E<r>s<slot>`.
    Subsurface { region: u16, basis: u16 },
}

impl PathVertex {
    /// `(editable region, coefficient slot)` of an editable or subsurface vertex; `None` for
    /// the fixed region.
    #[inline]
    pub fn slot(&self) -> Option<(u16, u16)> {
        match *self {
            PathVertex::Fixed => None,
            PathVertex::Editable { region, basis } | PathVertex::Subsurface { region, basis } => {
                Some((region, basis))
            }
        }
    }
}

/// The key of a layer: its path signature and its light group (0 = all lights).
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct LayerKey {
    /// Vertices from the eye towards the light; empty for the world seen directly.
    pub path: Vec<PathVertex>,
    /// Light group, for layers keyed by light; 0 when all lights share the layer.
    pub light_group: u16,
}

impl LayerKey {
    /// A key for `path` with all lights together.
    pub fn new(path: Vec<PathVertex>) -> Self {
        LayerKey {
            path,
            light_group: 0,
        }
    }

    /// Whether editable region `region` appears on this path (so its edits change the layer).
    pub fn contains_region(&self, region: u16) -> bool {
        self.path
            .iter()
            .any(|v| matches!(v.slot(), Some((r, _)) if r == region))
    }

    /// The EXR layer name: `World` for the empty path, else vertices joined by `_`, each `F`
    /// (fixed), `E<region>b<basis>` or `E<region>s<slot>` (subsurface), prefixed by `G<group>_` for a light group other than 0.
    /// Example: `E0b2_E1b0` is eye at editable region 0 basis 2, bounce at region 1 diffuse.
    pub fn layer_name(&self) -> String {
        let mut s = String::new();
        if self.light_group != 0 {
            let _ = write!(s, "G{}_", self.light_group);
        }
        if self.path.is_empty() {
            s.push_str("World");
        }
        for (i, v) in self.path.iter().enumerate() {
            if i > 0 {
                s.push('_');
            }
            match v {
                PathVertex::Fixed => s.push('F'),
                PathVertex::Editable { region, basis } => {
                    let _ = write!(s, "E{region}b{basis}");
                }
                PathVertex::Subsurface { region, basis } => {
                    let _ = write!(s, "E{region}s{basis}");
                }
            }
        }
        s
    }

    /// Parses a name written by [`LayerKey::layer_name`]; `None` for anything else.
    pub fn parse(name: &str) -> Option<Self> {
        let mut rest = name;
        let mut light_group = 0u16;
        if let Some(r) = rest.strip_prefix('G') {
            let (g, tail) = r.split_once('_')?;
            light_group = g.parse().ok()?;
            if light_group == 0 {
                return None;
            }
            rest = tail;
        }
        if rest == "World" {
            return Some(LayerKey {
                path: vec![],
                light_group,
            });
        }
        let mut path = Vec::new();
        for part in rest.split('_') {
            if part == "F" {
                path.push(PathVertex::Fixed);
            } else {
                let body = part.strip_prefix('E')?;
                if let Some((r, b)) = body.split_once('b') {
                    path.push(PathVertex::Editable {
                        region: r.parse().ok()?,
                        basis: b.parse().ok()?,
                    });
                } else {
                    let (r, b) = body.split_once('s')?;
                    path.push(PathVertex::Subsurface {
                        region: r.parse().ok()?,
                        basis: b.parse().ok()?,
                    });
                }
            }
        }
        if path.is_empty() {
            return None;
        }
        Some(LayerKey { path, light_group })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        let keys = [
            LayerKey::new(vec![]),
            LayerKey::new(vec![PathVertex::Fixed]),
            LayerKey::new(vec![
                PathVertex::Editable {
                    region: 0,
                    basis: 2,
                },
                PathVertex::Fixed,
            ]),
            LayerKey {
                path: vec![PathVertex::Editable {
                    region: 12,
                    basis: 5,
                }],
                light_group: 3,
            },
            LayerKey::new(vec![PathVertex::Subsurface {
                region: 1,
                basis: 9,
            }]),
            LayerKey {
                path: vec![PathVertex::Subsurface {
                    region: 0,
                    basis: 14,
                }],
                light_group: 2,
            },
        ];
        for k in keys {
            assert_eq!(
                LayerKey::parse(&k.layer_name()),
                Some(k.clone()),
                "{}",
                k.layer_name()
            );
        }
        for bad in [
            "", "E0", "X1b2", "G0_F", "E1b2_", "Ea b", "E1s", "Es2", "E1x2",
        ] {
            assert_eq!(LayerKey::parse(bad), None, "{bad}");
        }
    }
}
