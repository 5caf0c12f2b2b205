//! Finding and opening OpenImageDenoise at run time, and the C functions Relume calls.
//!
//! Why at run time: every Blender ships OIDN (the `lib` folder beside its binary; the `bpy`
//! wheel's `bpy/lib`), so inside Blender Relume uses that copy, the one Blender's own
//! threads already run, and elsewhere a system or packaged one; where there is none the
//! image falls back to the linear one with a message, and nothing fails to build or start.
//!
//! Search order ([`LibrarySearch`]): the file or folder named by [`ENV_VAR`], then the
//! folders the caller names (the add-on passes Blender's `lib` folder), then the platform's
//! library names as the system loader finds them. A library once opened is never closed: it
//! may have started thread pools (TBB) that must not lose their code while the process
//! lives.

use std::collections::HashMap;
use std::ffi::{c_char, c_void};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

use libloading::Library;

/// Names a library file (or a folder holding one) to try before any other.
pub const ENV_VAR: &str = "RELUME_OIDN_LIBRARY";

/// The file names of OIDN 2's main library on this platform, most specific first.
pub const LIBRARY_NAMES: &[&str] = if cfg!(target_os = "windows") {
    &["OpenImageDenoise.dll"]
} else if cfg!(target_os = "macos") {
    &["libOpenImageDenoise.2.dylib", "libOpenImageDenoise.dylib"]
} else {
    &["libOpenImageDenoise.so.2", "libOpenImageDenoise.so"]
};

/// Where to look for OIDN, in order: see the module doc.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LibrarySearch {
    /// Folders to look in after [`ENV_VAR`] (Blender's `lib` folder, the bpy wheel's).
    pub dirs: Vec<PathBuf>,
    /// Whether to ask the system loader for [`LIBRARY_NAMES`] last.
    pub system: bool,
}

impl LibrarySearch {
    /// [`ENV_VAR`], then `dirs`, then the system's names.
    pub fn with_dirs(dirs: Vec<PathBuf>) -> Self {
        LibrarySearch { dirs, system: true }
    }

    /// What will be tried, in order: (path or name, where it came from).
    pub fn candidates(&self) -> Vec<(PathBuf, String)> {
        let mut out = Vec::new();
        if let Some(v) = std::env::var_os(ENV_VAR).filter(|v| !v.is_empty()) {
            let p = PathBuf::from(v);
            if p.is_dir() {
                out.extend(
                    LIBRARY_NAMES
                        .iter()
                        .map(|n| (p.join(n), format!("{ENV_VAR} (a folder)"))),
                );
            } else {
                out.push((p, ENV_VAR.to_string()));
            }
        }
        for d in &self.dirs {
            out.extend(
                LIBRARY_NAMES
                    .iter()
                    .map(|n| (d.join(n), "a folder named by the caller".to_string())),
            );
        }
        if self.system {
            out.extend(
                LIBRARY_NAMES
                    .iter()
                    .map(|n| (PathBuf::from(n), "the system's library path".to_string())),
            );
        }
        out
    }

    /// Opens the first candidate that is an OIDN 2 library. Errors with every candidate
    /// and why it was passed over.
    pub fn open(&self) -> Result<&'static OidnApi, String> {
        let mut tried = Vec::new();
        for (path, source) in self.candidates() {
            // A path that names a folder or a file that is not there is passed over without
            // asking the loader (which would search elsewhere for a bare name).
            if path.components().count() > 1 && !path.is_file() {
                tried.push(format!("{} ({source}): no such file", path.display()));
                continue;
            }
            match OidnApi::open(&path) {
                Ok(api) => return Ok(api),
                Err(e) => tried.push(format!("{} ({source}): {e}", path.display())),
            }
        }
        Err(if tried.is_empty() {
            "no place to look for OpenImageDenoise was given".to_string()
        } else {
            format!(
                "OpenImageDenoise 2 was not found; tried {}",
                tried.join("; ")
            )
        })
    }
}

type Handle = *mut c_void;

/// The OIDN 2 C functions Relume uses, resolved from one opened library.
pub struct OidnApi {
    /// Where it was opened from (as given to the loader).
    pub path: PathBuf,
    pub new_device: unsafe extern "C" fn(i32) -> Handle,
    pub commit_device: unsafe extern "C" fn(Handle),
    pub release_device: unsafe extern "C" fn(Handle),
    pub get_device_error: unsafe extern "C" fn(Handle, *mut *const c_char) -> i32,
    pub get_device_int: unsafe extern "C" fn(Handle, *const c_char) -> i32,
    pub new_buffer: unsafe extern "C" fn(Handle, usize) -> Handle,
    pub release_buffer: unsafe extern "C" fn(Handle),
    pub write_buffer: unsafe extern "C" fn(Handle, usize, usize, *const c_void),
    pub read_buffer: unsafe extern "C" fn(Handle, usize, usize, *mut c_void),
    pub new_filter: unsafe extern "C" fn(Handle, *const c_char) -> Handle,
    #[allow(clippy::type_complexity)]
    pub set_filter_image:
        unsafe extern "C" fn(Handle, *const c_char, Handle, i32, usize, usize, usize, usize, usize),
    pub set_filter_bool: unsafe extern "C" fn(Handle, *const c_char, bool),
    pub set_filter_int: unsafe extern "C" fn(Handle, *const c_char, i32),
    pub commit_filter: unsafe extern "C" fn(Handle),
    pub execute_filter: unsafe extern "C" fn(Handle),
    pub release_filter: unsafe extern "C" fn(Handle),
}

// SAFETY: the table holds plain C function pointers into a library that is never unloaded;
// OIDN's API is thread-safe (calls on one device are serialised by the library).
unsafe impl Send for OidnApi {}
unsafe impl Sync for OidnApi {}

/// Opened libraries by path: each opened once, kept for the life of the process.
fn opened() -> &'static Mutex<HashMap<PathBuf, &'static OidnApi>> {
    static OPENED: OnceLock<Mutex<HashMap<PathBuf, &'static OidnApi>>> = OnceLock::new();
    OPENED.get_or_init(Default::default)
}

impl OidnApi {
    /// Opens `path` and resolves the functions; errors say what failed (the loader's
    /// message, or the first function missing: a library that is not OIDN 2).
    pub fn open(path: &Path) -> Result<&'static OidnApi, String> {
        let mut cache = opened().lock().unwrap_or_else(|e| e.into_inner());
        if let Some(api) = cache.get(path) {
            return Ok(api);
        }
        // SAFETY: opening runs the library's initialisers; OIDN's only set up its
        // registries. The library is leaked below, so no symbol outlives its code.
        let lib = unsafe { Library::new(path) }.map_err(|e| e.to_string())?;
        let lib: &'static Library = Box::leak(Box::new(lib));
        macro_rules! sym {
            ($name:literal) => {
                // SAFETY: the signature is OIDN 2's (oidn.h) for this name.
                *unsafe { lib.get(concat!($name, "\0").as_bytes()) }.map_err(|_| {
                    format!(
                        "it has no function {} (not an OpenImageDenoise 2 library)",
                        $name
                    )
                })?
            };
        }
        let api = OidnApi {
            path: path.to_path_buf(),
            new_device: sym!("oidnNewDevice"),
            commit_device: sym!("oidnCommitDevice"),
            release_device: sym!("oidnReleaseDevice"),
            get_device_error: sym!("oidnGetDeviceError"),
            get_device_int: sym!("oidnGetDeviceInt"),
            new_buffer: sym!("oidnNewBuffer"),
            release_buffer: sym!("oidnReleaseBuffer"),
            write_buffer: sym!("oidnWriteBuffer"),
            read_buffer: sym!("oidnReadBuffer"),
            new_filter: sym!("oidnNewFilter"),
            set_filter_image: sym!("oidnSetFilterImage"),
            set_filter_bool: sym!("oidnSetFilterBool"),
            set_filter_int: sym!("oidnSetFilterInt"),
            commit_filter: sym!("oidnCommitFilter"),
            execute_filter: sym!("oidnExecuteFilter"),
            release_filter: sym!("oidnReleaseFilter"),
        };
        let api: &'static OidnApi = Box::leak(Box::new(api));
        cache.insert(path.to_path_buf(), api);
        Ok(api)
    }
}
