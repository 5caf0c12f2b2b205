//! TEMPORARY stub (replaced by the stackio branch).
pub fn read_rgb_exr(path: &std::path::Path) -> crate::Result<(u32, u32, Vec<f32>)> {
    Err(crate::RelumeError::Image { path: path.into(), message: "not yet".into() })
}
