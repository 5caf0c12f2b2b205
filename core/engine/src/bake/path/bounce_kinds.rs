//! Cycles' light paths by kind: a path may take at most so many diffuse and so many glossy
//! bounces (Blender's defaults: Max 12, Diffuse 4, Glossy 4), not only so many in all.
//!
//! Cycles labels each bounce by the closure it sampled (the diffuse one or a glossy one) and
//! stops a path once a count reaches its limit: the vertex after that bounce still adds the
//! light its incoming ray met, but no direct light and no further bounce. A total cap alone
//! gives a path that alternates a metal floor and a white wall as few bounces as one that
//! only meets walls, so a room with a glossy floor came out darker than Cycles renders it.
//!
//! Relume's directions follow no closure (one draw from a region's mixture serves every
//! layer), so a bounce is not given a label: each one is diffuse with the probability of the
//! diffuse part of the vertex's BRDF along the drawn direction (luminance of that part over
//! the BRDF's), glossy otherwise — what Cycles' own choice of closure approaches where it
//! samples each closure in proportion to what it reflects. [`BounceKinds`] carries, along a
//! path, the probability of each split of its bounces into diffuse and glossy ones, and a
//! vertex's light is weighted by the probability that the path is still within the limits
//! there. The weight is that expectation over the labels taken exactly, so it adds no noise
//! and consumes no random numbers; it depends only on the BRDFs along the path (the
//! bake-time ones in the bake, so its layers stay linear in the edited coefficients).

use crate::bake::settings::{BakeSettings, MAX_BOUNCES};
use crate::Rgb;

/// Most diffuse-bounce counts a path carries at once (one per count 0..=[`MAX_BOUNCES`]).
const STATES: usize = MAX_BOUNCES as usize + 1;

/// The per-kind limits that can bind: a limit at or above the total cap never does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KindLimits {
    pub diffuse: u32,
    pub glossy: u32,
}

impl KindLimits {
    /// The limits of `settings` that bind on a path of at most `bounces` bounces.
    pub fn of(settings: &BakeSettings, bounces: u32) -> Option<Self> {
        KindLimits::binding(settings.diffuse_bounces, settings.glossy_bounces, bounces)
    }

    /// The limits for a path of at most `bounces` bounces; `None` when neither binds (then
    /// every path is within them and nothing needs to be carried).
    pub fn binding(diffuse: Option<u32>, glossy: Option<u32>, bounces: u32) -> Option<Self> {
        let diffuse = diffuse.unwrap_or(u32::MAX).min(bounces);
        let glossy = glossy.unwrap_or(u32::MAX).min(bounces);
        (diffuse < bounces || glossy < bounces).then_some(KindLimits { diffuse, glossy })
    }
}

/// The glossy share of a BRDF split into its diffuse and glossy parts: the probability a
/// bounce along that direction is labelled glossy (0 where the BRDF is black there).
#[inline]
pub fn glossy_share([diffuse, glossy]: [Rgb; 2]) -> f32 {
    let (d, g) = (
        crate::luminance(diffuse).max(0.0),
        crate::luminance(glossy).max(0.0),
    );
    if d + g > 0.0 && (d + g).is_finite() {
        (g / (d + g)).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// A BRDF's value from its diffuse and glossy parts
/// ([`crate::bake::path::surface_brdf::SurfaceBrdf::sum`]) with its [`glossy_share`], when
/// `share`, from the one evaluation that gave the parts.
#[inline]
pub fn value_and_share(parts: [Rgb; 2], share: bool) -> (Rgb, f32) {
    let value = crate::bake::path::surface_brdf::SurfaceBrdf::sum(parts);
    (value, if share { glossy_share(parts) } else { 0.0 })
}

/// The probability of each count of diffuse bounces among the `bounces` a path has taken
/// (the rest glossy), for the splits still within the limits.
#[derive(Clone, Debug)]
pub struct BounceKinds {
    limits: KindLimits,
    bounces: u32,
    /// `p[d]`: probability that `d` of the bounces were diffuse and the path is within the
    /// limits (a path past a limit never comes back, so its mass is dropped).
    p: [f32; STATES],
}

impl BounceKinds {
    /// A path at its first vertex: no bounce yet.
    pub fn new(limits: KindLimits) -> Self {
        let mut p = [0.0; STATES];
        p[0] = 1.0;
        BounceKinds {
            limits,
            bounces: 0,
            p,
        }
    }

    /// Probability that the path is within the limits at the vertex it has reached: the
    /// weight of that vertex's direct light and of the light its next ray meets.
    #[inline]
    pub fn within(&self) -> f32 {
        match self.range() {
            Some((lo, hi)) => self.p[lo..=hi].iter().sum::<f32>().clamp(0.0, 1.0),
            None => 0.0,
        }
    }

    /// One more bounce, glossy with probability `glossy` (else diffuse).
    pub fn bounce(&mut self, glossy: f32) {
        let glossy = glossy.clamp(0.0, 1.0);
        let before = self.range();
        self.bounces += 1;
        let Some((lo, hi)) = before else {
            return; // past the limits already: nothing left to carry
        };
        // Diffuse moves mass from d to d + 1; glossy keeps it at d. Descending, so each old
        // value is read before it is overwritten; mass past the diffuse limit drops out.
        let top = (hi + 1).min(self.limits.diffuse as usize).min(STATES - 1);
        for d in (lo..=top).rev() {
            let stay = if d <= hi { self.p[d] * glossy } else { 0.0 };
            let from_below = if d > lo {
                self.p[d - 1] * (1.0 - glossy)
            } else {
                0.0
            };
            self.p[d] = stay + from_below;
        }
        // Splits whose glossy count passed its limit drop out too.
        let keep_from = self.range().map_or(top + 1, |(new_lo, _)| new_lo);
        for v in &mut self.p[lo..keep_from.clamp(lo, top + 1)] {
            *v = 0.0;
        }
    }

    /// The diffuse counts that can still be within the limits after `self.bounces`; `None`
    /// when none can.
    #[inline]
    fn range(&self) -> Option<(usize, usize)> {
        let b = self.bounces;
        let lo = b.saturating_sub(self.limits.glossy) as usize;
        let hi = b.min(self.limits.diffuse) as usize;
        (lo <= hi).then_some((lo, hi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every label sequence enumerated: the probability the path is within the limits.
    fn enumerate(limits: KindLimits, shares: &[f32]) -> f32 {
        let n = shares.len();
        let mut total = 0.0f64;
        for bits in 0..(1u32 << n) {
            let (mut d, mut g, mut p) = (0u32, 0u32, 1.0f64);
            for (k, s) in shares.iter().enumerate() {
                if bits & (1 << k) != 0 {
                    g += 1;
                    p *= *s as f64;
                } else {
                    d += 1;
                    p *= 1.0 - *s as f64;
                }
            }
            if d <= limits.diffuse && g <= limits.glossy {
                total += p;
            }
        }
        total as f32
    }

    #[test]
    fn within_is_the_probability_over_every_labelling() {
        let shares = [0.3, 0.9, 0.0, 1.0, 0.5, 0.7, 0.2, 0.6];
        for (d, g) in [(4, 4), (2, 6), (0, 3), (3, 0), (1, 1), (8, 2)] {
            let limits = KindLimits {
                diffuse: d,
                glossy: g,
            };
            let mut kinds = BounceKinds::new(limits);
            assert_eq!(kinds.within(), 1.0);
            for k in 0..shares.len() {
                kinds.bounce(shares[k]);
                let want = enumerate(limits, &shares[..=k]);
                assert!(
                    (kinds.within() - want).abs() < 1e-5,
                    "limits {d}/{g} after {} bounces: {} against {want}",
                    k + 1,
                    kinds.within()
                );
            }
        }
    }

    #[test]
    fn a_diffuse_path_stops_at_the_diffuse_limit_and_a_glossy_one_at_the_glossy() {
        let limits = KindLimits {
            diffuse: 2,
            glossy: 3,
        };
        let (mut diffuse, mut glossy) = (BounceKinds::new(limits), BounceKinds::new(limits));
        for k in 1..=4 {
            diffuse.bounce(0.0);
            glossy.bounce(1.0);
            assert_eq!(diffuse.within(), if k <= 2 { 1.0 } else { 0.0 });
            assert_eq!(glossy.within(), if k <= 3 { 1.0 } else { 0.0 });
        }
    }

    #[test]
    fn limits_bind_only_below_the_total_cap() {
        assert_eq!(KindLimits::binding(None, None, 4), None);
        assert_eq!(KindLimits::binding(Some(4), Some(4), 4), None);
        assert_eq!(
            KindLimits::binding(Some(4), Some(4), 12),
            Some(KindLimits {
                diffuse: 4,
                glossy: 4
            })
        );
        assert_eq!(
            KindLimits::binding(Some(2), None, 6),
            Some(KindLimits {
                diffuse: 2,
                glossy: 6
            })
        );
    }

    #[test]
    fn the_glossy_share_follows_the_parts() {
        assert_eq!(glossy_share([Rgb::ONE, Rgb::ZERO]), 0.0);
        assert_eq!(glossy_share([Rgb::ZERO, Rgb::ONE]), 1.0);
        assert!((glossy_share([Rgb::ONE, Rgb::ONE * 3.0]) - 0.75).abs() < 1e-6);
        assert_eq!(glossy_share([Rgb::ZERO, Rgb::ZERO]), 0.0);
        // A negative part (the basis split can dip below zero) counts as none.
        assert_eq!(glossy_share([Rgb::ONE, -Rgb::ONE]), 0.0);
    }
}
