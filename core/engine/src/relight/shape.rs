//! What a relight needs to know of a stack besides its samples — its size, the editable
//! regions, the bases each region uses and the layers each region appears in — and the
//! checks every relighter makes on the stack and on the coefficients of an edit. The CPU
//! and the GPU relighters both build this one type, so a stack or an edit that one refuses
//! the other refuses too, in the same words. (Sample finiteness is checked where each
//! relighter reads the samples: its span scan on the CPU, its packing on the GPU.)

use crate::layer_key::LayerKey;
use crate::stack::tiled::TiledStack;
use crate::stack::{StackHeader, TransferStack};
use crate::{RelumeError, Result, Rgb};

use super::weight::group_factors_of;

/// The shape of a stack as the relight sees it.
#[derive(Clone, Debug)]
pub struct StackShape {
    pub width: usize,
    pub height: usize,
    /// Names of the editable regions, in editable order (`PathVertex::Editable::region`).
    pub editable_names: Vec<String>,
    /// Per editable region: the largest basis index in any key, plus one.
    pub basis_counts: Vec<usize>,
    /// Per editable region: the layers whose key contains it, ascending.
    pub region_layers: Vec<Vec<u32>>,
}

impl StackShape {
    /// Checks every layer of a dense stack and maps layers to the editable regions they
    /// depend on.
    ///
    /// Errors: a layer whose channel count is not 1 or 3, whose sample count is not
    /// width·height·channels, whose scale is not finite, whose key names an editable region
    /// the header does not have or a light group it does not have; a light tint that is not
    /// a finite non-negative colour.
    pub fn new(stack: &TransferStack) -> Result<StackShape> {
        let (width, height) = (stack.header.width as usize, stack.header.height as usize);
        for layer in &stack.layers {
            let expect = width * height * layer.channels as usize;
            if (layer.channels == 1 || layer.channels == 3) && layer.samples.len() != expect {
                return Err(RelumeError::invalid(
                    format!("layer {}", layer.key.layer_name()),
                    format!(
                        "{} samples, expected {width}×{height}×{} = {expect}",
                        layer.samples.len(),
                        layer.channels
                    ),
                ));
            }
        }
        Self::from_layers(
            &stack.header,
            stack.layers.iter().map(|l| (&l.key, l.channels, l.scale)),
        )
    }

    /// The shape of a tiled stack: its header and per-layer information (the tiles' own
    /// structure was checked when the stack was built or read). Errors as [`Self::new`]
    /// on the keys, channels, scales and light groups.
    pub fn from_tiled(stack: &TiledStack) -> Result<StackShape> {
        Self::from_layers(
            &stack.header,
            stack
                .layers
                .iter()
                .map(|l| (&l.key, l.channels as u32, l.scale)),
        )
    }

    /// The checks shared by both layouts, on `(key, channels, scale)` per layer id.
    fn from_layers<'a>(
        header: &StackHeader,
        layers: impl Iterator<Item = (&'a LayerKey, u32, f32)> + Clone,
    ) -> Result<StackShape> {
        let width = header.width as usize;
        let height = header.height as usize;
        let editable_names: Vec<String> = header
            .regions
            .iter()
            .filter(|r| r.editable)
            .map(|r| r.name.clone())
            .collect();
        let n_edit = editable_names.len();
        let mut basis_counts = vec![0usize; n_edit];
        let mut region_layers: Vec<Vec<u32>> = vec![Vec::new(); n_edit];
        for (i, (key, channels, scale)) in layers.clone().enumerate() {
            let name = key.layer_name();
            if channels != 1 && channels != 3 {
                return Err(RelumeError::invalid(
                    format!("layer {name}"),
                    format!("{channels} channels; a layer has 1 (grey) or 3 (RGB)"),
                ));
            }
            if !scale.is_finite() {
                return Err(RelumeError::NonFinite {
                    what: format!("scale of layer {name}"),
                });
            }
            for v in &key.path {
                if let Some(region) = v.region() {
                    let r = region as usize;
                    if r >= n_edit {
                        return Err(RelumeError::IndexOutOfRange {
                            what: format!("editable region of layer {name}"),
                            index: r as u64,
                            len: n_edit,
                        });
                    }
                    if let Some((_, basis)) = v.slot() {
                        basis_counts[r] = basis_counts[r].max(basis as usize + 1);
                    }
                    if region_layers[r].last() != Some(&(i as u32)) {
                        region_layers[r].push(i as u32);
                    }
                }
            }
        }
        // The light tints and every layer's light group, checked once here.
        group_factors_of(header, layers.map(|(k, _, _)| k), None)?;
        Ok(StackShape {
            width,
            height,
            editable_names,
            basis_counts,
            region_layers,
        })
    }

    /// Number of editable regions.
    pub fn editable_count(&self) -> usize {
        self.editable_names.len()
    }

    /// Number of bases the layers of editable region `region` use: the largest basis index
    /// in any key plus one (0 for a region no layer mentions or an index out of range).
    pub fn basis_count(&self, region: usize) -> usize {
        self.basis_counts.get(region).copied().unwrap_or(0)
    }

    /// Image width and height in pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// One coefficient list per editable region, each complete and finite.
    pub fn check_coefs(&self, coefs: &[Vec<Rgb>]) -> Result<()> {
        if coefs.len() != self.editable_count() {
            return Err(RelumeError::invalid(
                "relight coefficients",
                format!(
                    "{} coefficient lists for {} editable regions ({})",
                    coefs.len(),
                    self.editable_count(),
                    self.editable_names.join(", ")
                ),
            ));
        }
        coefs
            .iter()
            .enumerate()
            .try_for_each(|(r, c)| self.check_region(r, c))
    }

    /// `region` exists and `c` has at least its basis count of finite coefficients (more are
    /// accepted: a basis whose layers were all dropped as negligible leaves no key behind).
    pub fn check_region(&self, region: usize, c: &[Rgb]) -> Result<()> {
        let Some(name) = self.editable_names.get(region) else {
            return Err(RelumeError::IndexOutOfRange {
                what: "editable region to relight".into(),
                index: region as u64,
                len: self.editable_count(),
            });
        };
        if c.len() < self.basis_counts[region] {
            return Err(RelumeError::invalid(
                format!("coefficients of editable region {region} ({name})"),
                format!(
                    "{} given, but the stack's layers use {} bases",
                    c.len(),
                    self.basis_counts[region]
                ),
            ));
        }
        if let Some(b) = c.iter().position(|v| !v.is_finite()) {
            return Err(RelumeError::NonFinite {
                what: format!(
                    "coefficient {b} of editable region {region} ({name}): {:?}",
                    c[b]
                ),
            });
        }
        Ok(())
    }
}
