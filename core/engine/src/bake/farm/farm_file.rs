//! The container of the files a farm's tasks hand each other (the guide, the partial
//! stacks): a magic, a JSON header, a little-endian binary payload and an FNV-1a checksum of
//! header and payload, so a file truncated or damaged in a copy between machines is refused
//! by name instead of merged. Written atomically ([`crate::image_io::write_atomic`]).
//!
//! ```text
//! magic (8 bytes) | header length u64 | header JSON | payload length u64 | payload | checksum u64
//! ```

use std::fs::File;
use std::io::{BufReader, Read, Write};
use std::path::Path;

use crate::{RelumeError, Result};

/// Longest header accepted (a partial's header lists its blocks' layers: kilobytes).
const MAX_HEADER: u64 = 64 << 20;

const FNV_OFFSET: u64 = 0xcbf29ce484222325;
const FNV_PRIME: u64 = 0x100000001b3;

fn fnv(mut h: u64, bytes: &[u8]) -> u64 {
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(FNV_PRIME);
    }
    h
}

/// A writer of the payload that hashes what it writes.
pub struct PayloadWriter<'a, W: Write> {
    inner: &'a mut W,
    hash: u64,
    written: u64,
}

impl<W: Write> PayloadWriter<'_, W> {
    fn bytes(&mut self, path: &Path, b: &[u8]) -> Result<()> {
        self.hash = fnv(self.hash, b);
        self.written += b.len() as u64;
        self.inner
            .write_all(b)
            .map_err(|e| RelumeError::io(path, e))
    }

    /// Writes `bytes` as they are (a payload prepared elsewhere).
    pub fn raw(&mut self, path: &Path, bytes: &[u8]) -> Result<()> {
        self.bytes(path, bytes)
    }

    /// Writes `values` as little-endian f32.
    pub fn f32s(&mut self, path: &Path, values: &[f32]) -> Result<()> {
        let mut buf = Vec::with_capacity(4 * values.len().min(1 << 16));
        for chunk in values.chunks(1 << 16) {
            buf.clear();
            for v in chunk {
                buf.extend_from_slice(&v.to_le_bytes());
            }
            self.bytes(path, &buf)?;
        }
        Ok(())
    }

    /// Writes `values` as little-endian u64.
    pub fn u64s(&mut self, path: &Path, values: &[u64]) -> Result<()> {
        let buf: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.bytes(path, &buf)
    }
}

/// Writes `path` atomically: `magic`, `header` as JSON, a payload of `payload_len` bytes
/// that `payload` writes, the checksum.
pub fn write<H: serde::Serialize>(
    path: &Path,
    magic: &[u8; 8],
    header: &H,
    payload_len: u64,
    payload: impl FnOnce(&mut PayloadWriter<'_, std::io::BufWriter<File>>) -> Result<()>,
) -> Result<u64> {
    let json = serde_json::to_vec(header)
        .map_err(|e| RelumeError::invalid("farm file header", e.to_string()))?;
    crate::image_io::write_atomic(path, |w| {
        let io = |e| RelumeError::io(path, e);
        w.write_all(magic).map_err(io)?;
        w.write_all(&(json.len() as u64).to_le_bytes())
            .map_err(io)?;
        w.write_all(&json).map_err(io)?;
        w.write_all(&payload_len.to_le_bytes()).map_err(io)?;
        let mut p = PayloadWriter {
            inner: w,
            hash: fnv(FNV_OFFSET, &json),
            written: 0,
        };
        payload(&mut p)?;
        if p.written != payload_len {
            return Err(RelumeError::invalid(
                "farm file",
                format!("payload of {} bytes announced as {payload_len}", p.written),
            ));
        }
        let hash = p.hash;
        w.write_all(&hash.to_le_bytes()).map_err(io)?;
        Ok(())
    })
}

/// A reader of the payload that hashes what it reads and stops at its announced end.
pub struct PayloadReader<'a> {
    path: &'a Path,
    inner: BufReader<File>,
    hash: u64,
    left: u64,
}

impl PayloadReader<'_> {
    fn damaged(&self, message: impl Into<String>) -> RelumeError {
        RelumeError::StackTruncated {
            path: self.path.to_path_buf(),
            message: message.into(),
        }
    }

    fn bytes(&mut self, out: &mut [u8]) -> Result<()> {
        if out.len() as u64 > self.left {
            return Err(self.damaged("the payload is shorter than its header says"));
        }
        self.inner
            .read_exact(out)
            .map_err(|e| self.damaged(format!("reading the payload: {e}")))?;
        self.hash = fnv(self.hash, out);
        self.left -= out.len() as u64;
        Ok(())
    }

    /// Reads `n` little-endian f32 (memory checked first).
    pub fn f32s(&mut self, n: usize, what: &str) -> Result<Vec<f32>> {
        if (n as u64).saturating_mul(4) > self.left {
            return Err(self.damaged(format!(
                "{what}: the payload is shorter than its header says"
            )));
        }
        let mut out: Vec<f32> = crate::memory::try_with_capacity(n, what)?;
        let mut buf = vec![0u8; 4 << 16];
        let mut left = n;
        while left > 0 {
            let k = left.min(1 << 16);
            self.bytes(&mut buf[..4 * k])?;
            out.extend(
                buf[..4 * k]
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])),
            );
            left -= k;
        }
        Ok(out)
    }

    /// Reads `n` little-endian u64.
    pub fn u64s(&mut self, n: usize) -> Result<Vec<u64>> {
        if (n as u64).saturating_mul(8) > self.left {
            return Err(self.damaged("the payload is shorter than its header says"));
        }
        let mut buf = vec![0u8; 8 * n];
        self.bytes(&mut buf)?;
        Ok(buf
            .chunks_exact(8)
            .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect())
    }

    /// Checks that the payload was read to its end and the checksum matches; returns the
    /// checksum (the file's identity, e.g. the guide's hash recorded in partitions).
    pub fn finish(mut self) -> Result<u64> {
        if self.left != 0 {
            return Err(self.damaged(format!("{} payload bytes left unread", self.left)));
        }
        let mut sum = [0u8; 8];
        self.inner
            .read_exact(&mut sum)
            .map_err(|_| self.damaged("the checksum at the end is missing (truncated file)"))?;
        if u64::from_le_bytes(sum) != self.hash {
            return Err(self.damaged("checksum mismatch: the file was damaged or changed"));
        }
        let mut extra = [0u8; 1];
        if self
            .inner
            .read(&mut extra)
            .map_err(|e| RelumeError::io(self.path, e))?
            != 0
        {
            return Err(self.damaged("bytes after the checksum"));
        }
        Ok(self.hash)
    }
}

/// Opens `path`, checks `magic` (`kind` names the file in errors), parses the header and
/// returns it with a reader positioned at the payload.
pub fn read<'a, H: serde::de::DeserializeOwned>(
    path: &'a Path,
    magic: &[u8; 8],
    kind: &str,
) -> Result<(H, PayloadReader<'a>)> {
    let file = File::open(path).map_err(|e| RelumeError::io(path, e))?;
    let mut r = BufReader::with_capacity(1 << 20, file);
    let foreign = |m: String| RelumeError::StackForeign {
        path: path.to_path_buf(),
        message: m,
    };
    let mut m = [0u8; 8];
    r.read_exact(&mut m)
        .map_err(|_| foreign(format!("too short to be a {kind}")))?;
    if &m != magic {
        return Err(foreign(format!("not a {kind} (wrong magic bytes)")));
    }
    let damaged = |m: String| RelumeError::StackTruncated {
        path: path.to_path_buf(),
        message: m,
    };
    let mut len = [0u8; 8];
    r.read_exact(&mut len).map_err(|e| damaged(e.to_string()))?;
    let len = u64::from_le_bytes(len);
    if len > MAX_HEADER {
        return Err(damaged(format!("header of {len} bytes")));
    }
    let mut json = vec![0u8; len as usize];
    r.read_exact(&mut json)
        .map_err(|e| damaged(format!("header: {e}")))?;
    let header: H = serde_json::from_slice(&json).map_err(|e| RelumeError::StackFormat {
        path: path.to_path_buf(),
        message: format!("{kind} header: {e}"),
    })?;
    let mut plen = [0u8; 8];
    r.read_exact(&mut plen)
        .map_err(|e| damaged(e.to_string()))?;
    let left = u64::from_le_bytes(plen);
    let size = std::fs::metadata(path)
        .map_err(|e| RelumeError::io(path, e))?
        .len();
    if size != 8 + 8 + len + 8 + left.min(u64::MAX - 64) + 8 {
        return Err(damaged(format!(
            "{size} bytes on disk, {} expected from its header (truncated or damaged in a copy)",
            8 + 8 + len + 8 + left + 8
        )));
    }
    Ok((
        header,
        PayloadReader {
            path,
            inner: r,
            hash: fnv(FNV_OFFSET, &json),
            left,
        },
    ))
}
