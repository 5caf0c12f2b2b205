//! The built Principled basis on disk, so that a process that loads a stack (a relight, a
//! Blender session reopening a .blend, a farm merge) finds the basis instead of building it.
//!
//! # Why a cache and not the stack
//!
//! A build takes tens of seconds and its results (the bases at every quadrature node, their
//! tables, the metal curves) are tens of megabytes: several times a preview stack. They depend
//! on the basis configuration and the code alone, so one copy serves every stack baked with
//! that configuration, and a stack stays the size of its light.
//!
//! # Trust
//!
//! A file is used only when its key matches: the configuration, the engine version, the
//! target architecture and the source text of every file the build runs (so an edit to the
//! lobes, the quadrature, the PCA or the tables invalidates every cached basis without a
//! version bump anyone must remember). Its size must be what the configuration implies
//! before anything is read into memory, and a checksum covers every byte. Anything else — a
//! missing, truncated, damaged or foreign file — is ignored and the basis is built (and the
//! file replaced, atomically: a reader never sees half a file).
//!
//! Where: `RELUME_CACHE_DIR`, else `$XDG_CACHE_HOME/relume`, else `~/.cache/relume`;
//! `RELUME_CACHE_DIR=off` turns the cache off.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::scene::hash::fnv1a;

/// The first bytes of a cached basis.
const MAGIC: &[u8; 8] = b"RLMPBAS1";

/// The sources a build runs, by content: a change to any of them is a new key.
const BUILD_SOURCES: &[&str] = &[
    include_str!("mod.rs"),
    include_str!("lobes.rs"),
    include_str!("pca.rs"),
    include_str!("quadrature.rs"),
    include_str!("lune.rs"),
    include_str!("curves.rs"),
    include_str!("../cycles_principled/mod.rs"),
    include_str!("../cycles_principled/ggx.rs"),
    include_str!("../cycles_principled/quadrature.rs"),
    include_str!("../../linalg/mod.rs"),
    include_str!("../../linalg/gram.rs"),
    include_str!("../../linalg/pca.rs"),
    include_str!("../../linalg/eigen.rs"),
    include_str!("../../linalg/cholesky.rs"),
    include_str!("../../linalg/dense_solve.rs"),
];

/// What a build computes and a load restores: everything but the training lobes (cheap to
/// make again, and needed only by exact evaluation) and the quadrature nodes (likewise).
pub(crate) struct Stored {
    pub nspec: usize,
    pub coef: Vec<f64>,
    pub lobe_errors: Vec<f64>,
    pub norm: Vec<f64>,
    pub mean: Vec<f64>,
    pub at_nodes: Vec<f64>,
    pub table: Vec<f32>,
    pub curve_e_avg: Vec<f64>,
    pub curve_values: Vec<f64>,
    /// The build's report, as JSON.
    pub report: Vec<u8>,
}

/// The array lengths a configuration implies for `nspec` specular bases.
pub(crate) struct Shape {
    pub lobes: usize,
    pub nodes: usize,
    pub table_nodes: usize,
    pub curve_nodes: usize,
    pub curve_parts: usize,
}

impl Shape {
    fn lengths(&self, nspec: usize) -> [usize; 8] {
        [
            self.lobes * nspec,
            self.lobes,
            self.lobes,
            self.lobes,
            self.nodes * nspec,
            self.table_nodes * nspec,
            self.curve_nodes,
            self.curve_nodes * self.curve_parts * (1 + nspec),
        ]
    }

    /// Bytes of the arrays (f64 but the f32 table).
    fn array_bytes(&self, nspec: usize) -> usize {
        let l = self.lengths(nspec);
        l.iter().sum::<usize>() * 8 - l[5] * 4
    }
}

/// Most bytes a report may take (its JSON is a few hundred).
const MAX_REPORT: usize = 1 << 16;

/// The cache folder, or `None` when the cache is off or no home is known.
pub(crate) fn default_dir() -> Option<PathBuf> {
    match std::env::var_os("RELUME_CACHE_DIR") {
        Some(d) if d == "off" => None,
        Some(d) if !d.is_empty() => Some(PathBuf::from(d)),
        _ => std::env::var_os("XDG_CACHE_HOME")
            .filter(|d| !d.is_empty())
            .map(PathBuf::from)
            .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
            .map(|d| d.join("relume")),
    }
}

/// The key of a configuration (its serialised form, `config`) under this build of the engine.
pub(crate) fn key(config: &[u8]) -> u64 {
    let mut bytes = config.to_vec();
    bytes.extend_from_slice(env!("CARGO_PKG_VERSION").as_bytes());
    bytes.extend_from_slice(std::env::consts::ARCH.as_bytes());
    for source in BUILD_SOURCES {
        bytes.extend_from_slice(&fnv1a(source.as_bytes()).to_le_bytes());
    }
    fnv1a(&bytes)
}

/// The file of the basis with `key` in `dir`.
pub(crate) fn path(dir: &Path, key: u64) -> PathBuf {
    dir.join(format!("principled-basis-{key:016x}.bin"))
}

/// The stored basis with `key` in `dir`, of at most `max_nspec` specular bases, or `None`
/// when there is none that can be trusted.
pub(crate) fn load(dir: &Path, key: u64, max_nspec: usize, shape: &Shape) -> Option<Stored> {
    let path = path(dir, key);
    let size = std::fs::metadata(&path).ok()?.len() as usize;
    // Header: magic, key, nspec, report length; then the arrays, the report, the checksum.
    let header = MAGIC.len() + 8 + 8 + 8;
    let most = header + shape.array_bytes(max_nspec) + MAX_REPORT + 8;
    if size < header + 8 || size > most {
        return None;
    }
    let bytes = std::fs::read(&path).ok()?;
    let (body, sum) = bytes.split_at(bytes.len() - 8);
    if fnv1a(body).to_le_bytes() != sum {
        return None;
    }
    let mut r = Reader { bytes: body, at: 0 };
    if r.take(MAGIC.len())? != MAGIC || r.u64()? != key {
        return None;
    }
    let nspec = r.u64()? as usize;
    let report_len = r.u64()? as usize;
    if nspec == 0 || nspec > max_nspec || report_len > MAX_REPORT {
        return None;
    }
    if body.len() != header + shape.array_bytes(nspec) + report_len {
        return None;
    }
    let [coef, errors, norm, mean, at_nodes, table, e_avg, curves] = shape.lengths(nspec);
    let stored = Stored {
        nspec,
        coef: r.f64s(coef)?,
        lobe_errors: r.f64s(errors)?,
        norm: r.f64s(norm)?,
        mean: r.f64s(mean)?,
        at_nodes: r.f64s(at_nodes)?,
        table: r.f32s(table)?,
        curve_e_avg: r.f64s(e_avg)?,
        curve_values: r.f64s(curves)?,
        report: r.take(report_len)?.to_vec(),
    };
    Some(stored)
}

/// Writes `stored` under `key` into `dir` (made when missing) atomically: a temporary file
/// beside the final one, renamed over it. Failure leaves no partial file and is returned
/// for the caller to ignore (a cache that cannot be written only costs a later build).
pub(crate) fn store(dir: &Path, key: u64, stored: &Stored) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let mut body = Vec::new();
    body.extend_from_slice(MAGIC);
    body.extend_from_slice(&key.to_le_bytes());
    body.extend_from_slice(&(stored.nspec as u64).to_le_bytes());
    body.extend_from_slice(&(stored.report.len() as u64).to_le_bytes());
    for values in [
        &stored.coef,
        &stored.lobe_errors,
        &stored.norm,
        &stored.mean,
        &stored.at_nodes,
    ] {
        values
            .iter()
            .for_each(|v| body.extend_from_slice(&v.to_le_bytes()));
    }
    stored
        .table
        .iter()
        .for_each(|v| body.extend_from_slice(&v.to_le_bytes()));
    for values in [&stored.curve_e_avg, &stored.curve_values] {
        values
            .iter()
            .for_each(|v| body.extend_from_slice(&v.to_le_bytes()));
    }
    body.extend_from_slice(&stored.report);
    let sum = fnv1a(&body);
    let final_path = path(dir, key);
    let temp = dir.join(format!(
        ".{}.{}.tmp",
        final_path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        std::process::id()
    ));
    let written = (|| {
        let mut f = std::fs::File::create(&temp)?;
        f.write_all(&body)?;
        f.write_all(&sum.to_le_bytes())?;
        f.sync_all()?;
        std::fs::rename(&temp, &final_path)
    })();
    if written.is_err() {
        let _ = std::fs::remove_file(&temp);
    }
    written
}

/// Little-endian values off a byte slice; `None` past its end.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let end = self.at.checked_add(n)?;
        let s = self.bytes.get(self.at..end)?;
        self.at = end;
        Some(s)
    }

    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }

    fn f64s(&mut self, n: usize) -> Option<Vec<f64>> {
        let raw = self.take(n.checked_mul(8)?)?;
        Some(
            raw.chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
                .collect(),
        )
    }

    fn f32s(&mut self, n: usize) -> Option<Vec<f32>> {
        let raw = self.take(n.checked_mul(4)?)?;
        Some(
            raw.chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
                .collect(),
        )
    }
}
