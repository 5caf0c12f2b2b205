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
    /// Part `part` ([`PART_DIFFUSE`] or [`PART_GLOSSY`]) of editable region `region` at the
    /// eye of a tail-edit layer: weighs the part's energy now over its energy at bake time
    /// (`crate::relight::part_scales`). Named `P<region>d` or `P<region>g`.
    Part { region: u16, part: u8 },
    /// The tail-edit term of a layer: of the path's vertices beyond the first bounce,
    /// `diffuse` reflected through editable region `region`'s diffuse part and `glossy`
    /// through its glossy part; `bounce` is the part its bounce vertex reflected through
    /// when that vertex lay on the region too ([`BOUNCE_ELSEWHERE`] otherwise). Weighs
    /// s_b·(s_d^diffuse · s_g^glossy − 1), the s the region's part scales: 0 at the
    /// bake-time materials, so these layers only add what an edit changes in the tail.
    /// Named `T<region>d<diffuse>g<glossy>`, with `bd` or `bg` after it for the bounce part.
    /// The bake writes only [`BOUNCE_ELSEWHERE`] terms, the bounce vertex's part folded
    /// into the counts (`crate::bake::path::tail_edits::fold_bounce`: one layer where the
    /// part kept apart took three); `bd`/`bg` layers of the first tail-edit stacks still
    /// read and weigh as they were written.
    TailEdit {
        region: u16,
        diffuse: u8,
        glossy: u8,
        bounce: u8,
    },
}

/// [`PathVertex::TailEdit::bounce`] when the bounce vertex is not on the tail's region.
pub const BOUNCE_ELSEWHERE: u8 = 2;

/// The diffuse part of a region's material (its Kd / Base Color term).
pub const PART_DIFFUSE: u8 = 0;
/// The glossy part of a region's material (its Ks / specular and metallic term).
pub const PART_GLOSSY: u8 = 1;

fn part_letter(part: u8) -> char {
    if part == PART_DIFFUSE {
        'd'
    } else {
        'g'
    }
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
            PathVertex::Part { .. } | PathVertex::TailEdit { .. } => None,
        }
    }

    /// The editable region whose material this vertex's weight depends on, any kind.
    #[inline]
    pub fn region(&self) -> Option<u16> {
        match *self {
            PathVertex::Fixed => None,
            PathVertex::Editable { region, .. }
            | PathVertex::Subsurface { region, .. }
            | PathVertex::Part { region, .. }
            | PathVertex::TailEdit { region, .. } => Some(region),
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
        self.path.iter().any(|v| v.region() == Some(region))
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
                PathVertex::Part { region, part } => {
                    let _ = write!(s, "P{region}{}", part_letter(*part));
                }
                PathVertex::TailEdit {
                    region,
                    diffuse,
                    glossy,
                    bounce,
                } => {
                    let _ = write!(s, "T{region}d{diffuse}g{glossy}");
                    if *bounce != BOUNCE_ELSEWHERE {
                        s.push('b');
                        s.push(part_letter(*bounce));
                    }
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
            } else if let Some(body) = part.strip_prefix('P') {
                let (region, part) = parse_part(body)?;
                if part.1.is_empty() {
                    path.push(PathVertex::Part {
                        region,
                        part: part.0,
                    });
                } else {
                    return None;
                }
            } else if let Some(body) = part.strip_prefix('T') {
                let (region, rest) = body.split_once('d')?;
                let (diffuse, rest) = rest.split_once('g')?;
                let (glossy, bounce) = match rest.find('b') {
                    Some(at) => (
                        &rest[..at],
                        match &rest[at..] {
                            "bd" => PART_DIFFUSE,
                            "bg" => PART_GLOSSY,
                            _ => return None,
                        },
                    ),
                    None => (rest, BOUNCE_ELSEWHERE),
                };
                let all_digits = |d: &str| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit());
                if !all_digits(region) || !all_digits(diffuse) || !all_digits(glossy) {
                    return None;
                }
                let (diffuse, glossy): (u8, u8) = (diffuse.parse().ok()?, glossy.parse().ok()?);
                if diffuse == 0 && glossy == 0 {
                    return None;
                }
                path.push(PathVertex::TailEdit {
                    region: region.parse().ok()?,
                    diffuse,
                    glossy,
                    bounce,
                });
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

/// `<region><d|g><rest>` → (region, (part, rest)).
fn parse_part(body: &str) -> Option<(u16, (u8, &str))> {
    let at = body.find(['d', 'g'])?;
    let digits = &body[..at];
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let part = if &body[at..=at] == "d" {
        PART_DIFFUSE
    } else {
        PART_GLOSSY
    };
    Some((digits.parse().ok()?, (part, &body[at + 1..])))
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
            LayerKey {
                path: vec![
                    PathVertex::Part {
                        region: 1,
                        part: PART_GLOSSY,
                    },
                    PathVertex::TailEdit {
                        region: 0,
                        diffuse: 2,
                        glossy: 1,
                        bounce: PART_GLOSSY,
                    },
                ],
                light_group: 1,
            },
            LayerKey::new(vec![
                PathVertex::Fixed,
                PathVertex::TailEdit {
                    region: 12,
                    diffuse: 0,
                    glossy: 1,
                    bounce: BOUNCE_ELSEWHERE,
                },
            ]),
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
            "", "E0", "X1b2", "G0_F", "E1b2_", "Ea b", "E1s", "Es2", "E1x2", "P1", "P1d2", "Pd",
            "T0d", "T0d0g0", "T0x1", "Td1g0", "T0d1g0c", "T0d1g0bb", "T0d1", "T0d1g0bx",
        ] {
            assert_eq!(LayerKey::parse(bad), None, "{bad}");
        }
    }
}
