//! GPU context: the adapter is chosen on purpose, described once, and its errors become
//! `Error::Gpu` instead of panics.

use super::timer::PassTotals;
use crate::error::{Error, Result};
use std::sync::{Arc, Mutex};

/// Environment variable that picks an adapter by (case-insensitive) substring of its name.
pub const ADAPTER_ENV: &str = "WGPU_ADAPTER_NAME";

/// A device and queue plus what we learned about the adapter.
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
    /// Errors the device reported outside an error scope (e.g. during `poll`); they fail the
    /// next `check_errors`.
    uncaptured: Arc<Mutex<Vec<String>>>,
    /// The device has timestamp queries (the adapter offers `TIMESTAMP_QUERY`).
    timestamps: bool,
    int64_atomics: bool,
    maps_storage: bool,
    /// GPU time per pass while timing is on (`--timings`); None: passes are not timed.
    pass_times: Mutex<Option<PassTotals>>,
    /// Objects built once per device and kept (see [`GpuContext::cached`]).
    kept: Mutex<std::collections::HashMap<String, Arc<dyn std::any::Any + Send + Sync>>>,
    /// Buffers and textures kept for the next call that asks for the same ([`super::pool`]).
    pub(super) pool: Mutex<super::pool::Pool>,
}

/// What an adapter is, for `coif info` and logs.
pub fn describe(info: &wgpu::AdapterInfo) -> String {
    format!(
        "{} ({:?}, {:?}, driver {} {})",
        info.name, info.device_type, info.backend, info.driver, info.driver_info
    )
}

fn instance() -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    // Vulkan, Metal and DX12 carry full compute; WGPU_BACKEND may narrow the set.
    desc.backends = wgpu::Backends::PRIMARY.with_env();
    wgpu::Instance::new(desc)
}

/// Every adapter wgpu can see, for `coif info`.
pub fn list_adapters() -> Vec<wgpu::AdapterInfo> {
    let inst = instance();
    pollster::block_on(inst.enumerate_adapters(wgpu::Backends::all()))
        .iter()
        .map(|a| a.get_info())
        .collect()
}

/// Whether a hardware GPU (anything but a CPU adapter) is present. Used by `--backend auto`.
pub fn hardware_gpu_present() -> bool {
    list_adapters()
        .iter()
        .any(|i| i.device_type != wgpu::DeviceType::Cpu)
}

/// Ranks adapters: an explicit name match wins, then discrete, integrated, virtual, CPU.
fn rank(info: &wgpu::AdapterInfo) -> u32 {
    match info.device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

impl GpuContext {
    /// Opens the best adapter: `WGPU_ADAPTER_NAME` when set, else a hardware GPU, else a
    /// software one (lavapipe). Fails with `Error::NoAdapter` when nothing matches.
    pub fn new() -> Result<Self> {
        let inst = instance();
        let adapters = pollster::block_on(inst.enumerate_adapters(wgpu::Backends::all()));
        let wanted = std::env::var(ADAPTER_ENV).ok().filter(|s| !s.is_empty());
        let chosen = match &wanted {
            Some(name) => {
                let lname = name.to_lowercase();
                adapters
                    .into_iter()
                    .find(|a| a.get_info().name.to_lowercase().contains(&lname))
                    .ok_or_else(|| {
                        Error::NoAdapter(format!(
                            "{ADAPTER_ENV}={name} matches no adapter (see `coif info`)"
                        ))
                    })?
            }
            None => adapters
                .into_iter()
                .min_by_key(|a| rank(&a.get_info()))
                .ok_or_else(|| {
                    Error::NoAdapter(
                        "no Vulkan, Metal or DX12 adapter found; on Debian/Ubuntu install \
                         the software one with `apt-get install mesa-vulkan-drivers`, or use \
                         `--backend cpu`"
                            .into(),
                    )
                })?,
        };
        let info = chosen.get_info();
        let adapter_limits = chosen.limits();
        // Ask for the adapter's own storage limits: the defaults (128 MiB bindings) are
        // what lavapipe offers anyway, and real GPUs allow more.
        let required_limits = wgpu::Limits {
            max_storage_buffer_binding_size: adapter_limits.max_storage_buffer_binding_size,
            max_buffer_size: adapter_limits.max_buffer_size,
            max_storage_buffers_per_shader_stage: adapter_limits
                .max_storage_buffers_per_shader_stage,
            max_compute_invocations_per_workgroup: adapter_limits
                .max_compute_invocations_per_workgroup,
            max_compute_workgroup_size_x: adapter_limits.max_compute_workgroup_size_x,
            max_compute_workgroup_size_y: adapter_limits.max_compute_workgroup_size_y,
            max_compute_workgroups_per_dimension: adapter_limits
                .max_compute_workgroups_per_dimension,
            ..wgpu::Limits::default()
        };
        // Timestamps only when the adapter has them: GPU time per pass for `--timings`.
        let timestamps = chosen.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let mut required_features = if timestamps {
            wgpu::Features::TIMESTAMP_QUERY
        } else {
            wgpu::Features::empty()
        };
        // 64-bit atomic minima when the adapter has them: the strand rasteriser's one-walk
        // visibility (`wgsl/render/strand_vis64.wgsl`).
        let int64 = wgpu::Features::SHADER_INT64 | wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX;
        let int64_atomics = chosen.features().contains(int64);
        if int64_atomics {
            required_features |= int64;
        }
        // On a CPU driver device memory is host memory: buffers the host fills once may then
        // be mapped for writing directly (no staging copy), `GpuContext::maps_storage`.
        let maps_storage = info.device_type == wgpu::DeviceType::Cpu
            && chosen
                .features()
                .contains(wgpu::Features::MAPPABLE_PRIMARY_BUFFERS);
        if maps_storage {
            required_features |= wgpu::Features::MAPPABLE_PRIMARY_BUFFERS;
        }
        let (device, queue) = pollster::block_on(chosen.request_device(&wgpu::DeviceDescriptor {
            label: Some("coif"),
            required_features,
            required_limits: required_limits.clone(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| Error::NoAdapter(format!("{}: request_device failed: {e}", info.name)))?;
        let uncaptured = Arc::new(Mutex::new(Vec::new()));
        let sink = uncaptured.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            sink.lock().unwrap().push(e.to_string());
        }));
        log::info!(
            "GPU adapter: {}; max storage binding {} B, max buffer {} B, timestamp queries {}, \
             64-bit atomics {}",
            describe(&info),
            required_limits.max_storage_buffer_binding_size,
            required_limits.max_buffer_size,
            if timestamps { "yes" } else { "no" },
            if int64_atomics { "yes" } else { "no" }
        );
        Ok(GpuContext {
            device,
            queue,
            info,
            limits: required_limits,
            uncaptured,
            timestamps,
            int64_atomics,
            maps_storage,
            pass_times: Mutex::new(None),
            kept: Mutex::new(Default::default()),
            pool: Mutex::new(Default::default()),
        })
    }

    /// The value kept under `key`, built by `make` the first time it is asked for: for
    /// pipelines a host would otherwise build on every call (a software driver compiles
    /// each one, tens of milliseconds for the raster's). A key names one type.
    pub fn cached<T: Send + Sync + 'static>(&self, key: &str, make: impl FnOnce() -> T) -> Arc<T> {
        let mut kept = self.kept.lock().unwrap();
        if let Some(v) = kept.get(key) {
            if let Ok(v) = Arc::clone(v).downcast::<T>() {
                return v;
            }
        }
        let v = Arc::new(make());
        kept.insert(key.to_string(), v.clone());
        v
    }

    /// Whether the device has timestamp queries.
    pub fn has_timestamps(&self) -> bool {
        self.timestamps
    }

    /// Whether the device has 64-bit atomic min/max in shaders (and they were enabled).
    pub fn has_int64_atomics(&self) -> bool {
        self.int64_atomics
    }

    /// Whether storage buffers may be created mappable for writing (`MAP_WRITE`), which the
    /// context allows on CPU drivers only: there the mapping is the buffer's own memory, on
    /// a real GPU it would be slow memory for the shaders.
    pub fn maps_storage(&self) -> bool {
        self.maps_storage
    }

    /// Starts timing every pass from now on; false when the device has no timestamps.
    pub fn time_passes(&self) -> bool {
        if self.timestamps {
            self.pass_times
                .lock()
                .unwrap()
                .get_or_insert_with(Default::default);
        }
        self.timestamps
    }

    /// Whether passes are being timed.
    pub fn timing_passes(&self) -> bool {
        self.pass_times.lock().unwrap().is_some()
    }

    pub(super) fn add_pass_times<'a>(&self, times: impl Iterator<Item = (&'a str, f64)>) {
        if let Some(t) = self.pass_times.lock().unwrap().as_mut() {
            for (label, seconds) in times {
                t.add(label, seconds);
            }
        }
    }

    /// The pass times since timing started or since the last call (then reset); None when
    /// passes are not timed.
    pub fn take_pass_times(&self) -> Option<Vec<crate::timings::PassTime>> {
        self.pass_times
            .lock()
            .unwrap()
            .as_mut()
            .map(|t| std::mem::take(t).into_list())
    }

    /// Largest buffer one binding may hold.
    pub fn max_binding_bytes(&self) -> u64 {
        self.limits
            .max_storage_buffer_binding_size
            .min(self.limits.max_buffer_size)
    }

    /// Turns errors the device raised outside a scope into an `Error`.
    pub fn check_errors(&self) -> Result<()> {
        let mut errs = self.uncaptured.lock().unwrap();
        if errs.is_empty() {
            Ok(())
        } else {
            let msg = errs.join("; ");
            errs.clear();
            Err(Error::Gpu(msg))
        }
    }
}
