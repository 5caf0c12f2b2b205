//! What ran on the shown image, for the reports (`relume relight`, the bindings, the add-on).

use std::path::PathBuf;

use crate::DenoiseMode;

/// Which denoiser produced the shown image, and why that one.
#[derive(Clone, Debug, PartialEq)]
pub struct DenoiseReport {
    /// What the caller asked for.
    pub asked: DenoiseMode,
    /// What ran: `Oidn`, or `Linear` when OIDN was asked for and could not run.
    pub ran: DenoiseMode,
    /// Why `ran` is not `asked`, or what OIDN ran without (no features); `None` otherwise.
    pub note: Option<String>,
    /// The features OIDN used: "albedo+normal" or "none" (empty when OIDN did not run).
    pub features: &'static str,
    /// The OIDN device ("CPU", "CUDA", …) and library, when OIDN ran.
    pub device: Option<String>,
    pub library: Option<PathBuf>,
    pub version: Option<String>,
    /// OIDN's filter quality, when OIDN ran.
    pub quality: Option<crate::oidn::Quality>,
    /// Colour values below zero (a basis's negative lobes summed into a pixel) that entered
    /// OIDN as 0, which takes only values ≥ 0; the image relit keeps them.
    pub negative_values: usize,
    /// Wall time of the denoiser, features' albedo included (0 when nothing ran).
    pub milliseconds: f64,
}

impl DenoiseReport {
    /// A report for a mode that runs nothing.
    pub fn nothing(asked: DenoiseMode, ran: DenoiseMode, note: Option<String>) -> Self {
        DenoiseReport {
            asked,
            ran,
            note,
            features: "",
            device: None,
            library: None,
            version: None,
            quality: None,
            negative_values: 0,
            milliseconds: 0.0,
        }
    }

    /// One line for a human: "OIDN 2.3.3 (CPU, albedo+normal) in 812 ms" or
    /// "linear (OpenImageDenoise 2 was not found; …)".
    pub fn summary(&self) -> String {
        match self.ran {
            DenoiseMode::Oidn => {
                let mut s = format!(
                    "OIDN {} ({}, {} quality, features: {}) in {:.0} ms",
                    self.version.as_deref().unwrap_or("?"),
                    self.device.as_deref().unwrap_or("?"),
                    self.quality.map_or("?", |q| q.as_str()),
                    self.features,
                    self.milliseconds
                );
                if let Some(n) = &self.note {
                    s.push_str(&format!("; {n}"));
                }
                s
            }
            other => match &self.note {
                Some(n) => format!("{other} ({n})"),
                None => other.to_string(),
            },
        }
    }
}
