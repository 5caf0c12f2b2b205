//! `--denoise oidn|linear|none`: what the shown image is.

use std::fmt;
use std::str::FromStr;

/// What is done to the relit image before it is shown or written.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum DenoiseMode {
    /// Through OpenImageDenoise with the pixel features, when it is found (else as
    /// [`DenoiseMode::Linear`], with a note saying why).
    #[default]
    Oidn,
    /// The relit image as it is: the sum of the stack's layers, which the bake's linear
    /// (per-layer) denoiser already filtered where the preset asked for it. Nothing more
    /// runs at relight time; it is the same image as [`DenoiseMode::None`], named for
    /// what stands in for OIDN.
    Linear,
    /// The relit image exactly as summed, bit for bit.
    None,
}

impl DenoiseMode {
    pub fn as_str(self) -> &'static str {
        match self {
            DenoiseMode::Oidn => "oidn",
            DenoiseMode::Linear => "linear",
            DenoiseMode::None => "none",
        }
    }
}

impl fmt::Display for DenoiseMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for DenoiseMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "oidn" => Ok(DenoiseMode::Oidn),
            "linear" => Ok(DenoiseMode::Linear),
            "none" => Ok(DenoiseMode::None),
            other => Err(format!(
                "denoise \"{other}\": expected \"oidn\", \"linear\" or \"none\""
            )),
        }
    }
}
