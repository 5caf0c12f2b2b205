//! Sizes in bytes as people read them. A leaf: the error messages ([`crate::error`]) and the
//! memory budget ([`crate::memory`]) both print sizes, and neither imports the other for it.

/// `1536 MiB`-style text for messages.
pub fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    if bytes == u64::MAX {
        return "more than 16 EiB (the size overflows)".into();
    }
    let mut v = bytes as f64;
    let mut unit = 0;
    while v >= 1024.0 && unit + 1 < UNITS.len() {
        v /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{v:.1} {}", UNITS[unit])
    }
}
