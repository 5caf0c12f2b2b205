//! [`ShownImage`]: the relit image as it is shown — through OIDN with the pixel features,
//! or the linear image — and the report of which it was.
//!
//! The relit image itself stays the exact linear function of the stack; this only decides
//! what is displayed or written from it. When OIDN is asked for and cannot run (not found,
//! not version 2, a device error, an output that is not finite) the linear image is shown
//! and the report's note says why: the image is never missing for want of a denoiser.

use std::borrow::Cow;
use std::time::Instant;

use relume_engine::{RelumeError, Result};

use crate::oidn::{DeviceChoice, LibrarySearch, OidnApi, OidnDenoiser, Quality};
use crate::{DenoiseMode, DenoiseReport};

/// The auxiliary images OIDN may use, or why there are none.
pub enum FeatureImages<'a> {
    /// Albedo and normal, RGB per pixel, rows as the colour's, free of noise.
    Clean {
        albedo: &'a [f32],
        normal: &'a [f32],
    },
    /// None, and why (said in the report's note).
    Missing(String),
}

/// The denoiser of the shown image, kept between images: see the module doc.
pub struct ShownImage {
    search: LibrarySearch,
    choice: DeviceChoice,
    quality: Quality,
    /// Made at the first OIDN request; the reason it could not be, kept so the search runs
    /// once.
    oidn: Option<std::result::Result<OidnDenoiser, String>>,
}

impl ShownImage {
    pub fn new(search: LibrarySearch, choice: DeviceChoice) -> Self {
        ShownImage {
            search,
            choice,
            quality: Quality::High,
            oidn: None,
        }
    }

    /// OIDN's filter quality for the next images: `High` (the default, for renders) or
    /// `Balanced` (OIDN's advice for interactive use: about a third of the time on this
    /// project's CPU, docs/denoise.md).
    pub fn set_quality(&mut self, quality: Quality) {
        self.quality = quality;
    }

    /// The OIDN denoiser, made on first use, or why there is none.
    pub fn oidn(&mut self) -> std::result::Result<&mut OidnDenoiser, String> {
        if self.oidn.is_none() {
            let made = self
                .search
                .open()
                .and_then(|api: &'static OidnApi| OidnDenoiser::new(api, self.choice));
            self.oidn = Some(made);
        }
        match self.oidn.as_mut().expect("set above") {
            Ok(d) => Ok(d),
            Err(e) => Err(e.clone()),
        }
    }

    /// The shown image of `rgba` (RGBA per pixel, rows top first, `width × height`, every
    /// value finite: the relit image after [`relume_engine::relight::check_finite_image`])
    /// under `mode`. OIDN denoises RGB; alpha is kept. Errors only for an image of the wrong
    /// size or with a value that is not finite; every failure of OIDN itself falls back.
    pub fn show<'a>(
        &mut self,
        rgba: &'a [f32],
        width: u32,
        height: u32,
        mode: DenoiseMode,
        features: FeatureImages<'_>,
    ) -> Result<(Cow<'a, [f32]>, DenoiseReport)> {
        let pixels = width as usize * height as usize;
        if rgba.len() != pixels * 4 {
            return Err(RelumeError::invalid(
                "shown image",
                format!(
                    "{} values for {width}×{height} RGBA pixels ({} expected)",
                    rgba.len(),
                    pixels * 4
                ),
            ));
        }
        if mode != DenoiseMode::Oidn {
            return Ok((
                Cow::Borrowed(rgba),
                DenoiseReport::nothing(mode, mode, None),
            ));
        }
        relume_engine::relight::check_finite_image(rgba, width)?;
        let t = Instant::now();
        let fallback = |reason: String| {
            let report = DenoiseReport::nothing(
                DenoiseMode::Oidn,
                DenoiseMode::Linear,
                Some(format!("OpenImageDenoise did not run: {reason}")),
            );
            Ok((Cow::Borrowed(rgba), report))
        };
        let quality = self.quality;
        let denoiser = match self.oidn() {
            Ok(d) => d,
            Err(e) => return fallback(e),
        };
        denoiser.set_quality(quality);
        // OIDN takes HDR colour in [0, ∞): a value below zero enters as 0 (counted).
        let mut negative_values = 0usize;
        let mut color = Vec::with_capacity(pixels * 3);
        for px in rgba.chunks_exact(4) {
            for &v in &px[..3] {
                if v < 0.0 {
                    negative_values += 1;
                    color.push(0.0);
                } else {
                    color.push(v);
                }
            }
        }
        let (aux, note) = match features {
            FeatureImages::Clean { albedo, normal } => (Some((albedo, normal)), None),
            FeatureImages::Missing(why) => (None, Some(format!("no features: {why}"))),
        };
        let (w, h) = (width as usize, height as usize);
        let out = match denoiser.denoise(&color, aux, true, w, h) {
            Ok(out) => out,
            Err(e) => return fallback(e),
        };
        if let Some(i) = out.iter().position(|v| !v.is_finite()) {
            return fallback(format!(
                "its output has a value that is not finite at pixel ({}, {})",
                i / 3 % w,
                i / 3 / w
            ));
        }
        let mut shown = rgba.to_vec();
        for (dst, src) in shown.chunks_exact_mut(4).zip(out.chunks_exact(3)) {
            dst[..3].copy_from_slice(src);
        }
        let report = DenoiseReport {
            asked: DenoiseMode::Oidn,
            ran: DenoiseMode::Oidn,
            note,
            features: if aux.is_some() {
                "albedo+normal"
            } else {
                "none"
            },
            device: Some(denoiser.device_kind().to_string()),
            library: Some(denoiser.library().to_path_buf()),
            version: Some(denoiser.version_text()),
            quality: Some(quality),
            negative_values,
            milliseconds: t.elapsed().as_secs_f64() * 1e3,
        };
        Ok((Cow::Owned(shown), report))
    }
}
