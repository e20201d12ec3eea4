//! wgpu set-up: pick an adapter, open a device, move buffers to and from it.
//!
//! Any backend wgpu offers (Vulkan, Metal, DX12, GL) works. Software adapters (device type
//! `Cpu`: lavapipe, llvmpipe) are real and correct but slower than the native CPU backend on
//! the same cores, so `auto` only takes hardware adapters; `gpu` takes whatever there is.

use wgpu::util::DeviceExt;

use crate::error::{one_line, Error, Result};

/// Which adapter a bake may use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum DeviceChoice {
    /// A hardware GPU if there is one, else the CPU backend.
    #[default]
    Auto,
    /// Any GPU adapter, software ones (lavapipe) included; an error if there is none.
    Gpu,
    /// The CPU backend.
    Cpu,
}

/// One adapter as `prt-gpu devices` shows it.
#[derive(Clone, Debug)]
pub struct AdapterSummary {
    pub name: String,
    pub backend: wgpu::Backend,
    pub device_type: wgpu::DeviceType,
    pub driver: String,
    pub max_storage_buffer_binding_size: u64,
    pub max_buffer_size: u64,
    pub max_compute_workgroups_per_dimension: u32,
    pub max_compute_invocations_per_workgroup: u32,
}

impl AdapterSummary {
    fn of(adapter: &wgpu::Adapter) -> Self {
        let info = adapter.get_info();
        let limits = adapter.limits();
        AdapterSummary {
            name: info.name,
            backend: info.backend,
            device_type: info.device_type,
            driver: format!("{} {}", info.driver, info.driver_info)
                .trim()
                .to_string(),
            max_storage_buffer_binding_size: limits.max_storage_buffer_binding_size,
            max_buffer_size: limits.max_buffer_size,
            max_compute_workgroups_per_dimension: limits.max_compute_workgroups_per_dimension,
            max_compute_invocations_per_workgroup: limits.max_compute_invocations_per_workgroup,
        }
    }

    pub fn is_software(&self) -> bool {
        self.device_type == wgpu::DeviceType::Cpu
    }

    /// "name (backend, type)", for summaries.
    pub fn label(&self) -> String {
        format!("{} ({:?}, {:?})", self.name, self.backend, self.device_type)
    }
}

/// An open device and what it was opened on.
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub adapter: AdapterSummary,
    pub limits: wgpu::Limits,
    /// Kept for what the device cannot answer, such as which formats can be rendered to.
    handle: wgpu::Adapter,
}

impl GpuContext {
    /// Whether the device writes timestamps at the start and end of compute passes.
    pub fn has_timestamps(&self) -> bool {
        self.device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
    }
}

/// A `WGPU_BACKEND` that names no backend leaves wgpu with none, which would read as "no GPU
/// here": say what is wrong with the variable instead.
pub fn check_backend_variable() -> Result<()> {
    let Some(value) = std::env::var_os("WGPU_BACKEND") else {
        return Ok(());
    };
    let value = value.to_string_lossy();
    match wgpu::Backends::from_comma_list(&value).is_empty() {
        true => Err(Error::Gpu(format!(
            "WGPU_BACKEND={value:?} names no backend (vulkan, metal, dx12 or gl)"
        ))),
        false => Ok(()),
    }
}

fn instance() -> wgpu::Instance {
    // Honours WGPU_BACKEND and friends, so a user can force e.g. the GL backend.
    wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env())
}

fn all_adapters(instance: &wgpu::Instance) -> Vec<wgpu::Adapter> {
    let mut adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
    // Best first: hardware before software, then native APIs before GL.
    adapters.sort_by_key(|a| {
        let info = a.get_info();
        let kind = match info.device_type {
            wgpu::DeviceType::DiscreteGpu => 0,
            wgpu::DeviceType::IntegratedGpu => 1,
            wgpu::DeviceType::VirtualGpu => 2,
            wgpu::DeviceType::Other => 3,
            wgpu::DeviceType::Cpu => 4,
        };
        let api = match info.backend {
            wgpu::Backend::Vulkan | wgpu::Backend::Metal | wgpu::Backend::Dx12 => 0,
            _ => 1,
        };
        (kind, api)
    });
    adapters
}

/// Every adapter wgpu can see, best first.
pub fn list_adapters() -> Vec<AdapterSummary> {
    all_adapters(&instance())
        .iter()
        .map(AdapterSummary::of)
        .collect()
}

/// Opens a device for `choice`. `Ok(None)` means: bake on the CPU backend (asked for, or
/// `auto` found no hardware adapter). `name_filter` keeps adapters whose name contains it.
pub fn open(choice: DeviceChoice, name_filter: Option<&str>) -> Result<Option<GpuContext>> {
    if choice == DeviceChoice::Cpu {
        return Ok(None);
    }
    check_backend_variable()?;
    let instance = instance();
    let adapters = all_adapters(&instance);
    let candidates: Vec<&wgpu::Adapter> = match name_filter {
        Some(filter) => {
            let wanted = filter.to_lowercase();
            let found: Vec<_> = adapters
                .iter()
                .filter(|a| a.get_info().name.to_lowercase().contains(&wanted))
                .collect();
            if found.is_empty() {
                let names: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
                return Err(Error::Gpu(format!(
                    "no adapter name contains {filter:?} (adapters: {})",
                    if names.is_empty() {
                        "none".to_string()
                    } else {
                        names.join(", ")
                    }
                )));
            }
            found
        }
        None => adapters.iter().collect(),
    };
    let chosen = match (choice, candidates.first()) {
        (_, None) => {
            return match choice {
                DeviceChoice::Auto => Ok(None),
                _ => Err(Error::Gpu(
                    "no GPU adapter found (for a software one, install Mesa's lavapipe: \
                     apt-get install mesa-vulkan-drivers libvulkan1)"
                        .to_string(),
                )),
            }
        }
        // auto skips software rasterizers unless the user named one.
        (DeviceChoice::Auto, Some(a))
            if name_filter.is_none() && a.get_info().device_type == wgpu::DeviceType::Cpu =>
        {
            return Ok(None)
        }
        (_, Some(a)) => *a,
    };
    open_adapter(chosen).map(Some)
}

fn open_adapter(adapter: &wgpu::Adapter) -> Result<GpuContext> {
    let summary = AdapterSummary::of(adapter);
    // Ask for everything the adapter offers: the bake sizes its chunks by these limits.
    let limits = adapter.limits();
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("prt-gpu device"),
        // Timestamps where the adapter has them: the bake then times its kernels on the
        // device (`bake::gpu::GpuRun::kernel_seconds`), apart from the host's share.
        required_features: adapter.features() & wgpu::Features::TIMESTAMP_QUERY,
        required_limits: limits.clone(),
        experimental_features: wgpu::ExperimentalFeatures::disabled(),
        memory_hints: wgpu::MemoryHints::Performance,
        trace: wgpu::Trace::Off,
    }))
    .map_err(|e| Error::Gpu(format!("{}: cannot open device: {e}", summary.name)))?;
    Ok(GpuContext {
        device,
        queue,
        adapter: summary,
        limits,
        handle: adapter.clone(),
    })
}

impl GpuContext {
    /// A read-only storage buffer holding `data`. wgpu rejects empty bindings, so an empty
    /// slice becomes one zeroed element (kernels never read it: counts come from parameters).
    pub fn storage<T: bytemuck::Pod>(&self, label: &str, data: &[T]) -> wgpu::Buffer {
        let zero = [T::zeroed()];
        let contents = if data.is_empty() { &zero[..] } else { data };
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::cast_slice(contents),
                usage: wgpu::BufferUsages::STORAGE,
            })
    }

    /// A zeroed read-write storage buffer of `bytes` bytes that can be copied out.
    pub fn output(&self, label: &str, bytes: u64) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes.max(4),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// A uniform buffer for kernel parameters, rewritten before each submission.
    pub fn uniform<T: bytemuck::Pod>(&self, label: &str, value: &T) -> wgpu::Buffer {
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::bytes_of(value),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            })
    }

    /// Copies `bytes` bytes of `source` back to the host. A storage buffer cannot be mapped
    /// directly, so it goes through a MAP_READ staging copy.
    pub fn read_back<T: bytemuck::Pod>(&self, source: &wgpu::Buffer, bytes: u64) -> Result<Vec<T>> {
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("read-back staging"),
            size: bytes.max(4),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("read back"),
            });
        encoder.copy_buffer_to_buffer(source, 0, &staging, 0, bytes);
        self.queue.submit([encoder.finish()]);
        let (sender, receiver) = std::sync::mpsc::channel();
        staging.map_async(wgpu::MapMode::Read, .., move |r| {
            let _ = sender.send(r);
        });
        self.wait()?;
        receiver
            .recv()
            .map_err(|_| Error::Gpu("read-back was abandoned".into()))?
            .map_err(|e| Error::Gpu(format!("read-back failed: {e}")))?;
        let view = staging
            .get_mapped_range(..)
            .map_err(|e| Error::Gpu(format!("read-back failed: {e}")))?;
        let values = bytemuck::cast_slice::<u8, T>(&view[..bytes as usize]).to_vec();
        drop(view);
        staging.unmap();
        Ok(values)
    }

    /// What the adapter allows for `format` (downlevel backends such as GL cannot render to
    /// every format that WebGPU guarantees).
    pub fn format_features(&self, format: wgpu::TextureFormat) -> wgpu::TextureFormatFeatures {
        self.handle.get_texture_format_features(format)
    }

    /// A bind group with `buffers` at bindings 0, 1, 2, ... in order.
    pub fn bind_buffers(
        &self,
        label: &str,
        layout: &wgpu::BindGroupLayout,
        buffers: &[&wgpu::Buffer],
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout,
            entries: &entries,
        })
    }

    /// Blocks until the queue is idle.
    pub fn wait(&self) -> Result<()> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| Error::Gpu(format!("device poll failed: {e}")))
    }

    /// Runs `work` inside a validation error scope and turns a captured error into `Err`.
    pub fn checked<T>(&self, what: &str, work: impl FnOnce() -> T) -> Result<T> {
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let value = work();
        match pollster::block_on(scope.pop()) {
            None => Ok(value),
            Some(e) => Err(Error::Gpu(format!("{what}: {}", one_line(&e.to_string())))),
        }
    }
}

/// Whether a missing adapter must fail tests instead of skipping them: under CI, or when
/// PRT_GPU_REQUIRE_ADAPTER is set.
pub fn adapter_required() -> bool {
    let set =
        |name: &str| std::env::var(name).is_ok_and(|v| !v.is_empty() && v != "0" && v != "false");
    set("CI") || set("PRT_GPU_REQUIRE_ADAPTER")
}

/// Any adapter, for a check that needs one (the test suites): `None`, with the reason on
/// stderr, where there is none; a panic where one is required ([`adapter_required`]), so that
/// GPU tests never skip silently under CI.
pub fn any_adapter_or_skip() -> Option<GpuContext> {
    match open(DeviceChoice::Gpu, None) {
        Ok(Some(context)) => Some(context),
        Ok(None) => unreachable!("DeviceChoice::Gpu never falls back to the CPU"),
        Err(e) if adapter_required() => {
            panic!("no GPU adapter under CI (install mesa-vulkan-drivers): {e}")
        }
        Err(e) => {
            eprintln!("skipping the GPU check: {e}");
            None
        }
    }
}

/// The memory this machine can give a new process without swapping (Linux's `MemAvailable`),
/// in bytes; `None` where the platform does not say.
pub fn available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
