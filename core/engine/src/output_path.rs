//! The rule that a command never writes over one of its own inputs (`relume relight S.exr
//! -o S.exr` would replace the stack with an image; `relume bake X.json -o X.json` the scene).

use std::path::{Path, PathBuf};

use crate::{RelumeError, Result};

/// The path as the file system resolves it: canonical when it exists; else its canonical
/// parent joined with its file name (an output usually does not exist yet).
fn resolved(path: &Path) -> Option<PathBuf> {
    if let Ok(p) = path.canonicalize() {
        return Some(p);
    }
    let name = path.file_name()?;
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    Some(parent.canonicalize().ok()?.join(name))
}

/// Whether `a` and `b` are the same file: the same resolved path, or (on Unix, when both
/// exist) the same device and inode, which also catches hard links.
fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            return ma.dev() == mb.dev() && ma.ino() == mb.ino();
        }
    }
    match (resolved(a), resolved(b)) {
        (Some(x), Some(y)) => x == y,
        _ => false,
    }
}

/// Refuses `output` when it is one of `inputs` (each with the role it plays, e.g. "the
/// stack"), with [`RelumeError::OutputIsInput`]. Call it before reading anything.
pub fn refuse_output_over_inputs(output: &Path, inputs: &[(&Path, &str)]) -> Result<()> {
    for (input, role) in inputs {
        if same_file(output, input) {
            return Err(RelumeError::OutputIsInput {
                output: output.to_path_buf(),
                role: role.to_string(),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_file_by_another_spelling_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("s.exr");
        std::fs::write(&input, b"x").unwrap();
        let other_spelling = dir.path().join(".").join("s.exr");
        let e = refuse_output_over_inputs(&other_spelling, &[(&input, "the stack")]).unwrap_err();
        assert!(e.to_string().contains("the stack"), "{e}");
        let fresh = dir.path().join("out.exr");
        refuse_output_over_inputs(&fresh, &[(&input, "the stack")]).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn a_hard_link_to_the_input_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("scene.json");
        std::fs::write(&input, b"{}").unwrap();
        let link = dir.path().join("link.json");
        std::fs::hard_link(&input, &link).unwrap();
        assert!(refuse_output_over_inputs(&link, &[(&input, "the scene")]).is_err());
    }
}
