//! Hostile variants of a valid stack file, for the reader's tests and the fuzzers' seed
//! corpus: the same bytes with a header that claims more than the file holds.
//!
//! An OpenEXR file starts with a magic number and a version, then the header's attributes
//! (`name\0type\0size:i32 value`), ended by an empty name; the chunk offset table and the
//! pixel chunks follow. These helpers rewrite attributes and keep the rest as it is, so the
//! offsets no longer match either — exactly what a reader must survive.

/// One header attribute as stored.
struct Attribute {
    name: Vec<u8>,
    kind: Vec<u8>,
    value: Vec<u8>,
}

fn read_cstr(bytes: &[u8], at: &mut usize) -> Option<Vec<u8>> {
    let end = bytes.get(*at..)?.iter().position(|b| *b == 0)? + *at;
    let s = bytes[*at..end].to_vec();
    *at = end + 1;
    Some(s)
}

/// Splits a single-part file into (attributes, bytes after the header); `None` when the
/// bytes are not a single-part OpenEXR file.
fn split(bytes: &[u8]) -> Option<(Vec<Attribute>, &[u8])> {
    if bytes.get(..4)? != [0x76, 0x2f, 0x31, 0x01] {
        return None;
    }
    let mut at = 8;
    let mut attrs = Vec::new();
    loop {
        let name = read_cstr(bytes, &mut at)?;
        if name.is_empty() {
            return Some((attrs, &bytes[at..]));
        }
        let kind = read_cstr(bytes, &mut at)?;
        let size = i32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?) as usize;
        at += 4;
        let value = bytes.get(at..at + size)?.to_vec();
        at += size;
        attrs.push(Attribute { name, kind, value });
    }
}

fn join(head: &[u8], attrs: &[Attribute], rest: &[u8]) -> Vec<u8> {
    let mut out = head[..8].to_vec();
    for a in attrs {
        out.extend_from_slice(&a.name);
        out.push(0);
        out.extend_from_slice(&a.kind);
        out.push(0);
        out.extend_from_slice(&(a.value.len() as i32).to_le_bytes());
        out.extend_from_slice(&a.value);
    }
    out.push(0);
    out.extend_from_slice(rest);
    out
}

/// `bytes` (a stack file) rewritten so that its data and display windows and its Relume
/// header claim `width × height` pixels while the pixel data stays as small as it was.
/// `None` when `bytes` is not a single-part OpenEXR file with a Relume header.
pub fn with_claimed_size(bytes: &[u8], width: u32, height: u32) -> Option<Vec<u8>> {
    let (mut attrs, rest) = split(bytes)?;
    let window = {
        let mut v = Vec::new();
        for x in [0i32, 0, width as i32 - 1, height as i32 - 1] {
            v.extend_from_slice(&x.to_le_bytes());
        }
        v
    };
    let mut saw_header = false;
    for a in &mut attrs {
        match a.name.as_slice() {
            b"dataWindow" | b"displayWindow" => a.value = window.clone(),
            b"relume/header" => {
                let mut h: serde_json::Value = serde_json::from_slice(&a.value).ok()?;
                h["width"] = width.into();
                h["height"] = height.into();
                a.value = serde_json::to_vec(&h).ok()?;
                saw_header = true;
            }
            _ => {}
        }
    }
    saw_header.then(|| join(bytes, &attrs, rest))
}

/// `bytes` (a stack file) with its Relume header JSON rewritten by `edit` (a header that
/// claims a basis no build could afford, say); everything else as it was. `None` when
/// `bytes` is not a single-part OpenEXR file with a Relume header.
pub fn with_header_edit(
    bytes: &[u8],
    edit: impl FnOnce(&mut serde_json::Value),
) -> Option<Vec<u8>> {
    let (mut attrs, rest) = split(bytes)?;
    let a = attrs.iter_mut().find(|a| a.name == b"relume/header")?;
    let mut h: serde_json::Value = serde_json::from_slice(&a.value).ok()?;
    edit(&mut h);
    a.value = serde_json::to_vec(&h).ok()?;
    Some(join(bytes, &attrs, rest))
}

#[cfg(test)]
mod tests {
    #[test]
    fn refuses_bytes_that_are_not_a_stack() {
        assert!(super::with_claimed_size(b"not an exr file", 8, 8).is_none());
    }
}
