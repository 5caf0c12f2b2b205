//! One OIDN device and its "RT" filter, reused from image to image.
//!
//! Why buffers and copies rather than pointers to Relume's images: a GPU device (CUDA, HIP,
//! SYCL) cannot read memory from the system allocator, and OIDN's own buffers work on every
//! device. Creating a filter loads its network and is the slow part, so the filter and its
//! buffers are kept while the image size and the features stay the same.
//!
//! Every call is followed by a look at the device's error: a failure becomes an error
//! message naming the step and OIDN's own words, never a crash.

use std::ffi::{c_char, c_void, CStr, CString};

use super::library::OidnApi;

type Handle = *mut c_void;

const DEVICE_TYPE_DEFAULT: i32 = 0;
const DEVICE_TYPE_CPU: i32 = 1;
const FORMAT_FLOAT3: i32 = 3;

/// OIDN's filter quality (`OIDNQuality`): the trade of its network's precision for time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Quality {
    /// Final-frame quality, OIDN's default.
    #[default]
    High,
    /// Lower numerical precision where the device has it (OIDN's advice for interactive
    /// use); on many CPUs the same time as `High`.
    Balanced,
    /// Faster still, lower quality.
    Fast,
}

impl Quality {
    /// "high", "balanced" or "fast".
    pub fn as_str(self) -> &'static str {
        match self {
            Quality::High => "high",
            Quality::Balanced => "balanced",
            Quality::Fast => "fast",
        }
    }

    /// Parses a name written by [`Quality::as_str`].
    pub fn parse(name: &str) -> Result<Quality, String> {
        [Quality::High, Quality::Balanced, Quality::Fast]
            .into_iter()
            .find(|q| q.as_str() == name)
            .ok_or_else(|| format!("OIDN quality \"{name}\": expected high, balanced or fast"))
    }

    fn oidn(self) -> i32 {
        match self {
            Quality::High => 6,
            Quality::Balanced => 5,
            Quality::Fast => 4,
        }
    }
}

/// Which OIDN device to make.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DeviceChoice {
    /// OIDN's choice: the likely fastest device (a supported GPU, else the CPU).
    #[default]
    Default,
    /// The CPU device.
    Cpu,
}

/// The name of an `OIDNDeviceType`.
fn device_name(kind: i32) -> &'static str {
    match kind {
        1 => "CPU",
        2 => "SYCL",
        3 => "CUDA",
        4 => "HIP",
        5 => "Metal",
        _ => "unknown",
    }
}

/// The images one filter was set up for.
struct Filter {
    handle: Handle,
    width: usize,
    height: usize,
    with_features: bool,
    clean_features: bool,
    quality: Quality,
    /// color, albedo, normal, output (albedo and normal null without features).
    buffers: [Handle; 4],
}

/// An OIDN device with its filter: see the module doc.
pub struct OidnDenoiser {
    api: &'static OidnApi,
    device: Handle,
    kind: i32,
    version: i32,
    quality: Quality,
    filter: Option<Filter>,
}

// SAFETY: OIDN's API is thread-safe; the handles are only used through `&mut self`, so one
// thread at a time, and errors are read on the thread that made the call.
unsafe impl Send for OidnDenoiser {}

fn cstr(s: &str) -> CString {
    CString::new(s).expect("parameter names have no NUL")
}

impl OidnDenoiser {
    /// Creates and commits a device. Errors: OIDN's message when it makes none (no
    /// supported CPU or GPU), or a version other than 2.x.
    pub fn new(api: &'static OidnApi, choice: DeviceChoice) -> Result<Self, String> {
        let kind = match choice {
            DeviceChoice::Default => DEVICE_TYPE_DEFAULT,
            DeviceChoice::Cpu => DEVICE_TYPE_CPU,
        };
        // SAFETY: OIDN 2 C API calls with valid arguments; a null device is checked.
        let device = unsafe { (api.new_device)(kind) };
        if device.is_null() {
            let msg = error_message(api, std::ptr::null_mut())
                .unwrap_or_else(|| "no reason given".to_string());
            return Err(format!("OpenImageDenoise made no device: {msg}"));
        }
        let mut d = OidnDenoiser {
            api,
            device,
            kind: 0,
            version: 0,
            quality: Quality::default(),
            filter: None,
        };
        unsafe { (api.commit_device)(device) };
        d.check("committing the device")?;
        d.kind = d.device_int("type");
        d.version = d.device_int("version");
        let major = d.version / 10000;
        if major < 2 {
            return Err(format!(
                "OpenImageDenoise {} found at {}; Relume needs version 2 or later",
                d.version_text(),
                api.path.display()
            ));
        }
        Ok(d)
    }

    /// Sets the filter quality for the next images (the filter is set up again).
    pub fn set_quality(&mut self, quality: Quality) {
        self.quality = quality;
    }

    fn device_int(&self, name: &str) -> i32 {
        let n = cstr(name);
        // SAFETY: a committed device and a NUL-terminated name.
        unsafe { (self.api.get_device_int)(self.device, n.as_ptr()) }
    }

    /// "CPU", "CUDA", …: the device OIDN made.
    pub fn device_kind(&self) -> &'static str {
        device_name(self.kind)
    }

    /// The library's version, "2.3.3".
    pub fn version_text(&self) -> String {
        format!(
            "{}.{}.{}",
            self.version / 10000,
            self.version / 100 % 100,
            self.version % 100
        )
    }

    /// The library's path.
    pub fn library(&self) -> &std::path::Path {
        &self.api.path
    }

    /// The device's pending error as `Err("<what>: <OIDN's message>")`.
    fn check(&self, what: &str) -> Result<(), String> {
        match error_message(self.api, self.device) {
            None => Ok(()),
            Some(msg) => Err(format!("OpenImageDenoise failed {what}: {msg}")),
        }
    }

    /// Denoises `color` (RGB per pixel, HDR, finite and ≥ 0) of `width × height`, with
    /// `features` = (albedo, normal), same layout, when there are any; `clean_features` says
    /// they are free of noise (OIDN's `cleanAux`). Returns the RGB output.
    pub fn denoise(
        &mut self,
        color: &[f32],
        features: Option<(&[f32], &[f32])>,
        clean_features: bool,
        width: usize,
        height: usize,
    ) -> Result<Vec<f32>, String> {
        let len = width * height * 3;
        if color.len() != len || features.is_some_and(|(a, n)| a.len() != len || n.len() != len) {
            return Err(format!(
                "OpenImageDenoise: images of the wrong size for {width}×{height}"
            ));
        }
        let with_features = features.is_some();
        let reuse = self.filter.as_ref().is_some_and(|f| {
            (
                f.width,
                f.height,
                f.with_features,
                f.clean_features,
                f.quality,
            ) == (width, height, with_features, clean_features, self.quality)
        });
        if !reuse {
            self.release_filter();
            self.filter = Some(self.make_filter(width, height, with_features, clean_features)?);
        }
        let f = self.filter.as_ref().expect("made above");
        let bytes = len * 4;
        let api = self.api;
        // SAFETY: each buffer holds `bytes` bytes (made for this size); the slices hold
        // `len` floats.
        unsafe {
            (api.write_buffer)(f.buffers[0], 0, bytes, color.as_ptr().cast());
            if let Some((albedo, normal)) = features {
                (api.write_buffer)(f.buffers[1], 0, bytes, albedo.as_ptr().cast());
                (api.write_buffer)(f.buffers[2], 0, bytes, normal.as_ptr().cast());
            }
        }
        self.check("copying the images in")?;
        unsafe { (api.execute_filter)(f.handle) };
        self.check("denoising")?;
        let mut out = vec![0.0f32; len];
        unsafe { (api.read_buffer)(f.buffers[3], 0, bytes, out.as_mut_ptr().cast()) };
        self.check("copying the image out")?;
        Ok(out)
    }

    fn make_filter(
        &mut self,
        width: usize,
        height: usize,
        with_features: bool,
        clean_features: bool,
    ) -> Result<Filter, String> {
        let api = self.api;
        let bytes = width * height * 3 * 4;
        let mut f = Filter {
            handle: std::ptr::null_mut(),
            width,
            height,
            with_features,
            clean_features,
            quality: self.quality,
            buffers: [std::ptr::null_mut(); 4],
        };
        let names = ["color", "albedo", "normal", "output"];
        // SAFETY: OIDN 2 C API calls on a committed device; every handle made is stored in
        // `f` first, so the error path releases it (`release`).
        let made = (|| {
            for (i, slot) in f.buffers.iter_mut().enumerate() {
                if (i == 1 || i == 2) && !with_features {
                    continue;
                }
                *slot = unsafe { (api.new_buffer)(self.device, bytes) };
                self.check("making a buffer")?;
                if slot.is_null() {
                    return Err("OpenImageDenoise made no buffer".to_string());
                }
            }
            let rt = cstr("RT");
            f.handle = unsafe { (api.new_filter)(self.device, rt.as_ptr()) };
            self.check("making the RT filter")?;
            if f.handle.is_null() {
                return Err("OpenImageDenoise made no RT filter".to_string());
            }
            for (i, name) in names.iter().enumerate() {
                if f.buffers[i].is_null() {
                    continue;
                }
                let n = cstr(name);
                unsafe {
                    (api.set_filter_image)(
                        f.handle,
                        n.as_ptr(),
                        f.buffers[i],
                        FORMAT_FLOAT3,
                        width,
                        height,
                        0,
                        0,
                        0,
                    )
                };
            }
            let (hdr, clean, quality) = (cstr("hdr"), cstr("cleanAux"), cstr("quality"));
            unsafe {
                (api.set_filter_bool)(f.handle, hdr.as_ptr(), true);
                (api.set_filter_int)(f.handle, quality.as_ptr(), f.quality.oidn());
                (api.set_filter_bool)(f.handle, clean.as_ptr(), with_features && clean_features);
                (api.commit_filter)(f.handle);
            }
            self.check("setting up the RT filter")
        })();
        match made {
            Ok(()) => Ok(f),
            Err(e) => {
                release(api, &f);
                Err(e)
            }
        }
    }

    fn release_filter(&mut self) {
        if let Some(f) = self.filter.take() {
            release(self.api, &f);
        }
    }
}

fn release(api: &OidnApi, f: &Filter) {
    // SAFETY: handles made by this device and released once (the filter is dropped after).
    unsafe {
        if !f.handle.is_null() {
            (api.release_filter)(f.handle);
        }
        for b in f.buffers {
            if !b.is_null() {
                (api.release_buffer)(b);
            }
        }
    }
}

impl Drop for OidnDenoiser {
    fn drop(&mut self) {
        self.release_filter();
        // SAFETY: the device was made by `new` and is released once.
        unsafe { (self.api.release_device)(self.device) };
    }
}

/// OIDN's pending error on `device` (null: why a device was not made), cleared.
fn error_message(api: &OidnApi, device: Handle) -> Option<String> {
    let mut msg: *const c_char = std::ptr::null();
    // SAFETY: OIDN writes a pointer to a string valid until the next call, copied at once.
    let code = unsafe { (api.get_device_error)(device, &mut msg) };
    if code == 0 {
        return None;
    }
    let text = if msg.is_null() {
        String::new()
    } else {
        unsafe { CStr::from_ptr(msg) }
            .to_string_lossy()
            .into_owned()
    };
    Some(format!("{text} (OIDN error {code})"))
}
