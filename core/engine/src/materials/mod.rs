//! Material edits applied at relight time, and every rule they must pass — one owner for
//! the command line's materials file, the Python bindings and the add-on (which calls the
//! bindings):
//! - `file`: the materials file (`relume relight --materials M.json`), its format and
//!   parser ([`MaterialsFile`], [`load_materials`], [`parse_materials`]);
//! - `resolve`: the rules — which regions may be edited, the values
//!   ([`crate::brdf::MaterialSpec::validate`]: Kd/Ks/ns, Principled inputs, subsurface) and
//!   the light-group gains ([`resolve_materials`], [`resolve_light_gains`]);
//! - `live`: a live session's current materials and what changed since the last image
//!   ([`LiveMaterials`]).
//!
//! The coefficients of a material for each slot of a region are the stack's bases'
//! ([`crate::stack::bases::StackBases`]).

mod file;
mod live;
mod resolve;

pub use file::{
    load_materials, parse_materials, LightGroupEdit, MaterialsFile, MATERIALS_FORMAT,
    MATERIALS_FORMAT_VERSION, MAX_LIGHT_GAIN,
};
pub use live::{LiveMaterials, LiveRelighter};
pub use resolve::{resolve_light_gains, resolve_materials};
