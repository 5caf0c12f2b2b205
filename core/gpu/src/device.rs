//! Which device relights: a real GPU through wgpu, or the CPU loop of the engine.
//!
//! `auto` takes the GPU only when the best adapter is a real one (discrete, integrated or
//! virtual). A software adapter (lavapipe / llvmpipe, `DeviceType::Cpu`) is correct but
//! far slower than the CPU loop, by orders of magnitude (`docs/measurements.md`). So `auto`
//! leaves it to tests that force `gpu`. The reason for the choice is a sentence
//! the command line prints and the add-on shows.
//!
//! Backends: Vulkan, Metal and DX12 (every current GPU has one of them). GL is left out:
//! on a headless Linux machine it only adds llvmpipe again, and it cannot bind 6 storage
//! buffers in a compute shader on many drivers.

use std::fmt;
use std::str::FromStr;

use crate::error::GpuError;

/// What the caller asks for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DevicePreference {
    /// A real GPU if there is one, else the CPU.
    #[default]
    Auto,
    /// The best adapter whatever it is, software ones included; an error if there is none.
    Gpu,
    /// The CPU loop.
    Cpu,
}

impl FromStr for DevicePreference {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "auto" => Ok(DevicePreference::Auto),
            "gpu" => Ok(DevicePreference::Gpu),
            "cpu" => Ok(DevicePreference::Cpu),
            _ => Err(format!("device \"{s}\": expected auto, gpu or cpu")),
        }
    }
}

/// What actually relights.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeviceKind {
    Gpu,
    Cpu,
}

impl fmt::Display for DeviceKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            DeviceKind::Gpu => "gpu",
            DeviceKind::Cpu => "cpu",
        })
    }
}

/// The outcome of [`choose_device`].
pub struct DeviceChoice {
    pub kind: DeviceKind,
    /// Why, in one sentence starting with "GPU:" or "CPU:".
    pub reason: String,
    /// The adapter to build the GPU context on (`Some` exactly when `kind` is GPU).
    pub adapter: Option<wgpu::Adapter>,
}

/// Whether wgpu reports a hardware (or hardware-backed virtual) GPU.
pub fn is_real_gpu(device_type: wgpu::DeviceType) -> bool {
    matches!(
        device_type,
        wgpu::DeviceType::DiscreteGpu
            | wgpu::DeviceType::IntegratedGpu
            | wgpu::DeviceType::VirtualGpu
    )
}

/// "name (backend)" of an adapter, e.g. "llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan)" (Debug of the backend: capitalised).
pub fn adapter_label(info: &wgpu::AdapterInfo) -> String {
    format!("{} ({:?})", info.name, info.backend)
}

/// Chooses the device for `preference`. Errors only for [`DevicePreference::Gpu`] without
/// any adapter; `auto` without one falls back to the CPU and says why.
pub fn choose_device(preference: DevicePreference) -> Result<DeviceChoice, GpuError> {
    let cpu = |reason: String| DeviceChoice {
        kind: DeviceKind::Cpu,
        reason,
        adapter: None,
    };
    if preference == DevicePreference::Cpu {
        return Ok(cpu("CPU: chosen by the caller".into()));
    }
    let adapter = match best_adapter() {
        Ok(a) => a,
        Err(e) if preference == DevicePreference::Auto => {
            return Ok(cpu(format!("CPU: {e}")));
        }
        Err(e) => return Err(e),
    };
    let info = adapter.get_info();
    let label = adapter_label(&info);
    let real = is_real_gpu(info.device_type);
    match (preference, real) {
        (_, true) => Ok(DeviceChoice {
            kind: DeviceKind::Gpu,
            reason: format!("GPU: {label}"),
            adapter: Some(adapter),
        }),
        (DevicePreference::Auto, false) => Ok(cpu(format!(
            "CPU: the only adapter is {} ({label}), hundreds of times slower than the CPU loop",
            software_kind(info.device_type)
        ))),
        (_, false) => Ok(DeviceChoice {
            kind: DeviceKind::Gpu,
            reason: format!(
                "GPU (forced): {label}, {} — correct but hundreds of times slower than the CPU loop",
                software_kind(info.device_type)
            ),
            adapter: Some(adapter),
        }),
    }
}

fn software_kind(t: wgpu::DeviceType) -> &'static str {
    match t {
        wgpu::DeviceType::Cpu => "a software rasteriser",
        _ => "an adapter of unknown kind",
    }
}

/// The best adapter on any enabled backend: discrete before integrated before virtual
/// before unknown before software. `WGPU_BACKEND` and the other wgpu environment variables
/// are honoured.
fn best_adapter() -> Result<wgpu::Adapter, GpuError> {
    let instance =
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
    let rank = |a: &wgpu::Adapter| match a.get_info().device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    };
    if let Some(best) = adapters.into_iter().min_by_key(rank) {
        return Ok(best);
    }
    // No adapter: ask once more the usual way, for the backend's own words on why.
    let why = match pollster::block_on(instance.request_adapter(&Default::default())) {
        Ok(_) => "the adapter list was empty".to_string(),
        Err(e) => e.to_string(),
    };
    Err(GpuError::NoAdapter(why))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preferences_parse_and_cpu_needs_no_adapter() {
        assert_eq!("AUTO".parse(), Ok(DevicePreference::Auto));
        assert_eq!("gpu".parse(), Ok(DevicePreference::Gpu));
        assert!("cuda"
            .parse::<DevicePreference>()
            .unwrap_err()
            .contains("auto, gpu or cpu"));
        let c = choose_device(DevicePreference::Cpu).unwrap();
        assert_eq!(c.kind, DeviceKind::Cpu);
        assert!(c.adapter.is_none() && c.reason.starts_with("CPU:"));
    }

    #[test]
    fn only_hardware_types_are_real_gpus() {
        assert!(is_real_gpu(wgpu::DeviceType::DiscreteGpu));
        assert!(is_real_gpu(wgpu::DeviceType::VirtualGpu));
        assert!(!is_real_gpu(wgpu::DeviceType::Cpu));
        assert!(!is_real_gpu(wgpu::DeviceType::Other));
    }
}
