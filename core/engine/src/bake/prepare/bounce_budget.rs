//! What the bounce pre-pass ([`super::bounces`]) measured, and the rule that picks the bounce
//! count from it. Apart from the pre-pass because the bake context keeps the result (for the
//! bake's report), while the pre-pass traces through the context.

use serde::Serialize;

/// What the pre-pass measured.
#[derive(Clone, Debug, Serialize)]
pub struct BounceEstimate {
    /// The caller's cap (`BakeSettings::bounces`).
    pub cap: u32,
    /// Share of the light bounces past the chosen count may leave out.
    pub budget: f32,
    /// Bounces baked.
    pub chosen: u32,
    /// Mean image luminance brought by bounce 0 (direct), 1, …, cap.
    pub energy: Vec<f64>,
    /// Share of the measured light (bounces 0..=cap) in bounces chosen+1..=cap.
    pub left_out: f64,
    /// Paths traced.
    pub paths: u64,
}

/// The smallest n ≥ 1 (at most the cap, `energy.len() − 1`) whose bounces past n hold at most
/// `budget` of the total, and that share.
pub fn choose(energy: &[f64], budget: f32) -> (u32, f64) {
    let cap = energy.len().saturating_sub(1);
    let total: f64 = energy.iter().sum();
    let mut n = cap.min(1);
    loop {
        let rest: f64 = energy[n + 1..].iter().sum();
        let share = if total > 0.0 { rest / total } else { 0.0 };
        if n >= cap || share <= budget as f64 {
            return (n as u32, share);
        }
        n += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::choose;

    #[test]
    fn choose_keeps_the_first_bounce_and_stops_within_budget() {
        // A geometric series of ratio ½: bounces past n hold ≈ 2^-n of ≈ 2, a share 2^-(n+1).
        let energy: Vec<f64> = (0..=12).map(|k| 0.5f64.powi(k)).collect();
        let (n, share) = choose(&energy, 0.01);
        assert_eq!(n, 6, "share {share}");
        assert!(share <= 0.01);
        assert_eq!(choose(&energy, 0.9).0, 1, "never below one bounce");
        assert_eq!(choose(&energy, 0.0).0, 12, "a zero budget takes the cap");
        assert_eq!(choose(&[1.0, 0.0], 0.01).0, 1);
        assert_eq!(choose(&[1.0], 0.01).0, 0, "cap 0 stays 0");
    }
}
