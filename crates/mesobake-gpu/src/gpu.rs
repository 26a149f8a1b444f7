//! The GPU: which adapter (by name, from the command line or `MESOBAKE_ADAPTER`; otherwise
//! wgpu's default choice, honouring `WGPU_BACKEND` and `WGPU_POWER_PREF`) and its device.

use mesobake_core::error::{Error, Result};
use serde::Serialize;

/// The environment variable that names the adapter to use (a case-insensitive substring of
/// its name, e.g. `llvmpipe` for Mesa's software Vulkan driver).
pub const ADAPTER_ENV: &str = "MESOBAKE_ADAPTER";

/// What a preview ran on.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct AdapterDescription {
    /// The adapter's name as the driver reports it.
    pub name: String,
    /// Graphics API.
    pub backend: String,
    /// Discrete, integrated, virtual, CPU or other.
    pub device_type: String,
    /// Driver name and version.
    pub driver: String,
}

/// An opened adapter: its device and queue.
pub struct Gpu {
    /// The logical device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// What it is.
    pub adapter: AdapterDescription,
}

impl Gpu {
    /// Opens the adapter whose name contains `name` (case-insensitive), else the one named by
    /// [`ADAPTER_ENV`], else wgpu's default; a clear error when there is none.
    pub fn open(name: Option<&str>) -> Result<Gpu> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let wanted = name
            .map(str::to_owned)
            .or_else(|| std::env::var(ADAPTER_ENV).ok().filter(|s| !s.is_empty()));
        let adapter = match wanted {
            Some(wanted) => {
                let adapters =
                    pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
                let names: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
                let lower = wanted.to_lowercase();
                adapters
                    .into_iter()
                    .find(|a| a.get_info().name.to_lowercase().contains(&lower))
                    .ok_or_else(|| {
                        Error::Gpu(format!(
                            "no adapter's name contains {wanted:?}; available: {}",
                            if names.is_empty() {
                                "none".to_owned()
                            } else {
                                names.join(", ")
                            }
                        ))
                    })?
            }
            None => pollster::block_on(
                instance.request_adapter(&wgpu::RequestAdapterOptions {
                    power_preference: wgpu::PowerPreference::from_env()
                        .unwrap_or(wgpu::PowerPreference::HighPerformance),
                    ..Default::default()
                }),
            )
            .map_err(|e| {
                Error::Gpu(format!(
                    "no GPU adapter available ({e}); install a Vulkan driver (on Debian without \
                     a GPU: the package mesa-vulkan-drivers, Mesa's software rasterizer)"
                ))
            })?,
        };
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("mesobake preview"),
            required_limits: adapter.limits(),
            required_features: adapter.features()
                & (wgpu::Features::SHADER_EARLY_DEPTH_TEST | wgpu::Features::FLOAT32_BLENDABLE),
            ..Default::default()
        }))
        .map_err(|e| Error::Gpu(format!("opening {}: {e}", info.name)))?;
        Ok(Gpu {
            device,
            queue,
            adapter: AdapterDescription {
                name: info.name,
                backend: format!("{:?}", info.backend),
                device_type: format!("{:?}", info.device_type),
                driver: format!("{} {}", info.driver, info.driver_info)
                    .trim()
                    .to_owned(),
            },
        })
    }

    /// Runs `f` with validation and out-of-memory errors captured: wgpu reports them
    /// asynchronously, so they become this call's error instead of a panic.
    pub fn checked<T>(&self, what: &str, f: impl FnOnce() -> T) -> Result<T> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let value = f();
        let errors = [
            pollster::block_on(validation.pop()),
            pollster::block_on(oom.pop()),
        ];
        match errors.into_iter().flatten().next() {
            Some(e) => Err(Error::Gpu(format!("{what}: {e}"))),
            None => Ok(value),
        }
    }

    /// Loop iterations one shader invocation may run on this adapter and be sure that none
    /// was cut short. Mesa's software rasterizer (llvmpipe, lavapipe's) runs invocations in
    /// SIMD batches of (vector bits / 32) lanes and stops every loop of a batch once all of
    /// them together have run 65 535 iterations (measured on Mesa 22.3: one invocation's
    /// loops stop at 65 535; pixels of 300 iterations came out empty beside pixels of
    /// 16 000). A batch's total is at most its lanes times its largest invocation, so an
    /// invocation within 65 535 / lanes (less a margin) is safe. `None`: no such limit.
    pub fn loop_budget(&self) -> Option<u32> {
        let name = self.adapter.name.to_lowercase();
        if !name.contains("llvmpipe") {
            return None;
        }
        // "llvmpipe (LLVM 15.0.6, 256 bits)": 8 lanes of 32 bits; 16 where unreadable.
        let bits = name
            .split_whitespace()
            .zip(name.split_whitespace().skip(1))
            .find(|(_, unit)| unit.starts_with("bits"))
            .and_then(|(n, _)| n.parse::<u32>().ok())
            .unwrap_or(512);
        let lanes = (bits / 32).max(1);
        Some(65_535 / lanes - 64)
    }

    /// Waits until the queue has finished its work.
    pub fn wait(&self) -> Result<()> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| Error::Gpu(format!("waiting for the GPU: {e}")))
    }
}
