//! The rules that an output never destroys a file: a command never writes over one of its
//! own inputs (`relume relight S.exr -o S.exr` would replace the stack with an image;
//! `relume bake X.json -o X.json` the scene), two outputs of one command are never the same
//! file (`-o X.exr --png X.exr`), and an existing output that is not a regular file (a
//! device, FIFO, socket or directory) is refused, since the atomic write's rename would
//! replace it with a regular file (`-o /dev/null` as root would replace `/dev/null`).

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

/// What the file system object at `path` is, when it exists and is not a regular file
/// (symbolic links followed): "a directory", "a FIFO (named pipe)", … `None` when `path`
/// does not exist or is a regular file.
fn non_regular_kind(path: &Path) -> Option<&'static str> {
    let file_type = std::fs::metadata(path).ok()?.file_type();
    if file_type.is_file() {
        return None;
    }
    if file_type.is_dir() {
        return Some("a directory");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if file_type.is_fifo() {
            return Some("a FIFO (named pipe)");
        }
        if file_type.is_socket() {
            return Some("a socket");
        }
        if file_type.is_char_device() {
            return Some("a character device");
        }
        if file_type.is_block_device() {
            return Some("a block device");
        }
    }
    Some("a special file")
}

/// Refuses an existing `output` that is not a regular file, with
/// [`RelumeError::OutputNotAFile`]: every file Relume writes is renamed over its target
/// (the atomic write of `image_io.rs`), which would replace a device or FIFO with a regular
/// file. Refused rather than written through. The atomic write asks this too.
pub fn refuse_non_regular_output(output: &Path) -> Result<()> {
    match non_regular_kind(output) {
        Some(kind) => Err(RelumeError::OutputNotAFile {
            output: output.to_path_buf(),
            kind: kind.to_string(),
        }),
        None => Ok(()),
    }
}

/// The one check of a command's paths, before it reads anything: each of `outputs` (each
/// with its role, e.g. "the PNG") is refused when it exists and is not a regular file
/// ([`refuse_non_regular_output`]), when it is one of `inputs`
/// ([`refuse_output_over_inputs`]), or when it is another of `outputs`
/// ([`RelumeError::OutputsCollide`]: the second write would replace the first).
pub fn check_outputs(outputs: &[(&Path, &str)], inputs: &[(&Path, &str)]) -> Result<()> {
    for (i, (output, role)) in outputs.iter().enumerate() {
        refuse_non_regular_output(output)?;
        refuse_output_over_inputs(output, inputs)?;
        for (earlier, earlier_role) in &outputs[..i] {
            if same_file(output, earlier) {
                return Err(RelumeError::OutputsCollide {
                    output: output.to_path_buf(),
                    role: role.to_string(),
                    other_role: earlier_role.to_string(),
                });
            }
        }
    }
    Ok(())
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

    #[test]
    fn two_outputs_that_are_one_file_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("x.exr");
        let b = dir.path().join(".").join("x.exr");
        let e = check_outputs(&[(&a, "the image"), (&b, "the PNG")], &[]).unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("the PNG") && text.contains("the image") && text.contains("x.exr"),
            "{text}"
        );
        let c = dir.path().join("x.png");
        check_outputs(&[(&a, "the image"), (&c, "the PNG")], &[]).unwrap();
    }

    #[test]
    fn a_directory_is_refused_as_an_output() {
        let dir = tempfile::tempdir().unwrap();
        let e = check_outputs(&[(dir.path(), "the image")], &[]).unwrap_err();
        assert!(e.to_string().contains("is a directory"), "{e}");
    }
}
