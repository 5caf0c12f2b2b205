//! What a relight needs to know of a stack besides its samples — editable regions, bases
//! per region, the layers each region appears in, the light tint — and the checks of the
//! CPU relighter on the stack and on coefficients, with the same messages, so that a stack
//! or an edit the CPU refuses is refused on the GPU too. (Sample finiteness is checked
//! while packing, in `layout::pack_layer`.)

use relume_engine::stack::TransferStack;
use relume_engine::{RelumeError, Result, Rgb};

pub struct StackShape {
    pub width: usize,
    pub height: usize,
    pub editable_names: Vec<String>,
    /// Per editable region: the largest basis index in any key, plus one.
    pub basis_counts: Vec<usize>,
    /// Per editable region: the layers whose key contains it, ascending.
    pub region_layers: Vec<Vec<u32>>,
    /// The emitters' common colour; every layer weight is multiplied by it.
    /// Per layer-key light group, the factor of its layers (tint × live gain): see
    /// `relume_engine::relight::group_factors`.
    pub group_factors: Vec<Rgb>,
}

impl StackShape {
    pub fn new(stack: &TransferStack) -> Result<StackShape> {
        let width = stack.header.width as usize;
        let height = stack.header.height as usize;
        let editable_names: Vec<String> = stack
            .header
            .regions
            .iter()
            .filter(|r| r.editable)
            .map(|r| r.name.clone())
            .collect();
        let n_edit = editable_names.len();
        let mut basis_counts = vec![0usize; n_edit];
        let mut region_layers: Vec<Vec<u32>> = vec![Vec::new(); n_edit];
        for (i, layer) in stack.layers.iter().enumerate() {
            let name = layer.key.layer_name();
            if layer.channels != 1 && layer.channels != 3 {
                return Err(RelumeError::invalid(
                    format!("layer {name}"),
                    format!(
                        "{} channels; a layer has 1 (grey) or 3 (RGB)",
                        layer.channels
                    ),
                ));
            }
            let expect = width * height * layer.channels as usize;
            if layer.samples.len() != expect {
                return Err(RelumeError::invalid(
                    format!("layer {name}"),
                    format!(
                        "{} samples, expected {width}×{height}×{} = {expect}",
                        layer.samples.len(),
                        layer.channels
                    ),
                ));
            }
            if !layer.scale.is_finite() {
                return Err(RelumeError::NonFinite {
                    what: format!("scale of layer {name}"),
                });
            }
            for v in &layer.key.path {
                if let Some((region, basis)) = v.slot() {
                    let r = region as usize;
                    if r >= n_edit {
                        return Err(RelumeError::IndexOutOfRange {
                            what: format!("editable region of layer {name}"),
                            index: r as u64,
                            len: n_edit,
                        });
                    }
                    basis_counts[r] = basis_counts[r].max(basis as usize + 1);
                    if region_layers[r].last() != Some(&(i as u32)) {
                        region_layers[r].push(i as u32);
                    }
                }
            }
        }
        let group_factors = relume_engine::relight::group_factors(stack, None)?;
        Ok(StackShape {
            width,
            height,
            editable_names,
            basis_counts,
            region_layers,
            group_factors,
        })
    }

    /// One coefficient list per editable region, each complete and finite.
    pub fn check_coefs(&self, coefs: &[Vec<Rgb>]) -> Result<()> {
        if coefs.len() != self.editable_names.len() {
            return Err(RelumeError::invalid(
                "relight coefficients",
                format!(
                    "{} coefficient lists for {} editable regions ({})",
                    coefs.len(),
                    self.editable_names.len(),
                    self.editable_names.join(", ")
                ),
            ));
        }
        coefs
            .iter()
            .enumerate()
            .try_for_each(|(r, c)| self.check_region(r, c))
    }

    /// `region` exists and `c` has at least its basis count of finite coefficients.
    pub fn check_region(&self, region: usize, c: &[Rgb]) -> Result<()> {
        let Some(name) = self.editable_names.get(region) else {
            return Err(RelumeError::IndexOutOfRange {
                what: "editable region to relight".into(),
                index: region as u64,
                len: self.editable_names.len(),
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
