//! The last check on a relit image: every pixel finite. The inputs are bounded where they
//! enter (materials, light-group gains), but a stack may still hold values whose weighted
//! sum overflows f32; such an image is refused with what went wrong, never written as if
//! it were right.

use crate::{RelumeError, Result};

/// Errors ([`RelumeError::NonFinite`]) when a value of the RGBA `image` (`width` pixels a
/// row) is NaN or infinite, naming how many pixels are and the first one.
pub fn check_finite_image(image: &[f32], width: u32) -> Result<()> {
    let mut bad = image
        .chunks_exact(4)
        .enumerate()
        .filter(|(_, px)| px.iter().any(|v| !v.is_finite()));
    let Some((first, px)) = bad.next() else {
        return Ok(());
    };
    let count = 1 + bad.count();
    let w = width.max(1) as usize;
    Err(RelumeError::NonFinite {
        what: format!(
            "the relit image: {count} of {} pixels, the first at ({}, {}) = {:?} (the stack's layers times the materials and light-group gains overflow f32; lower the gains or rebake)",
            image.len() / 4,
            first % w,
            first / w,
            &px[..3]
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_the_count_and_the_first_non_finite_pixel() {
        let mut img = vec![0.5f32; 4 * 6];
        assert!(check_finite_image(&img, 3).is_ok());
        img[4 * 4] = f32::INFINITY;
        img[4 * 5 + 1] = f32::NAN;
        let e = check_finite_image(&img, 3).unwrap_err().to_string();
        assert!(
            e.contains("non-finite") && e.contains("2 of 6 pixels") && e.contains("(1, 1)"),
            "{e}"
        );
    }
}
