//! One engine, two backends (after vello's `Recording` + `WgpuEngine`).
//!
//! A stage is registered once as a [`StageDef`]: its WGSL source, its bindings and its CPU
//! mirror. Host code records uploads, dispatches and downloads into a [`Recording`]; the
//! [`Engine`] replays it either on a wgpu device or by calling the CPU mirrors on the same
//! buffers. That single switch is what makes every GPU-versus-CPU test cheap.

use crate::error::{Error, Result};
use crate::gpu::GpuContext;
use std::cell::{Ref, RefCell, RefMut};
use std::collections::HashMap;
use std::sync::Mutex;

/// The backend a command line asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BackendChoice {
    /// A hardware GPU when there is one, else the CPU mirrors.
    Auto,
    /// wgpu on the chosen adapter, software (lavapipe) included.
    Gpu,
    /// The CPU mirrors, in parallel on all cores.
    Cpu,
}

/// How a stage sees one binding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bind {
    Uniform,
    Read,
    ReadWrite,
}

/// The CPU mirror of a stage: the workgroup count it was dispatched with and its bindings,
/// in binding order.
pub type CpuStage = fn(workgroups: [u32; 3], bindings: &[CpuBinding]);

/// One compute stage: a WGSL file with a `main` entry point, and its CPU mirror.
pub struct StageDef {
    /// Label, also the WGSL file stem: `wgsl/<name>.wgsl`.
    pub name: &'static str,
    /// The file as written: its `#include` lines are expanded by [`crate::gpu::wgsl::compose`]
    /// when the module is created.
    pub wgsl: &'static str,
    pub bindings: &'static [Bind],
    pub cpu: CpuStage,
}

/// One render pass: a WGSL file with vertex and fragment entry points. Draws are not
/// recorded like dispatches; the host that builds the pipelines is `crate::render::raster`
/// and the CPU mirror, which reads like the shader, is `crate::stages::<name>`.
pub struct RenderStageDef {
    /// Label, also the WGSL file stem: `wgsl/render/<name>.wgsl`.
    pub name: &'static str,
    /// The file as written (see [`StageDef::wgsl`]).
    pub wgsl: &'static str,
    /// (vertex, fragment) entry points, one pair per pipeline the host builds from it.
    pub entry_points: &'static [(&'static str, &'static str)],
    /// Compute entry points, for a render pass done as compute passes (`strand_vis`).
    pub compute: &'static [&'static str],
    /// Whether the shader uses 64-bit atomic min/max (`SHADER_INT64_ATOMIC_MIN_MAX`), which
    /// only some devices have; the host checks [`crate::gpu::GpuContext::has_int64_atomics`].
    pub int64_atomics: bool,
}

/// A buffer as a CPU mirror sees it; backed by `u32` words so every 4-byte type casts.
pub struct CpuBinding<'a> {
    data: &'a RefCell<Vec<u32>>,
}

impl CpuBinding<'_> {
    pub fn get<T: bytemuck::Pod>(&self) -> Ref<'_, [T]> {
        Ref::map(self.data.borrow(), |v| bytemuck::cast_slice(v.as_slice()))
    }
    pub fn get_mut<T: bytemuck::Pod>(&self) -> RefMut<'_, [T]> {
        RefMut::map(self.data.borrow_mut(), |v| {
            bytemuck::cast_slice_mut(v.as_mut_slice())
        })
    }
    /// Reads a uniform written with encase.
    pub fn uniform<T: encase::ShaderType + encase::internal::CreateFrom>(&self) -> T {
        let words = self.data.borrow();
        let bytes: &[u8] = bytemuck::cast_slice(words.as_slice());
        encase::UniformBuffer::new(bytes)
            .create()
            .expect("uniform buffer matches its struct")
    }
}

/// A buffer in a recording.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BufProxy {
    id: usize,
    /// Size in bytes (a multiple of 4).
    pub size: u64,
}

enum Cmd {
    Create {
        buf: BufProxy,
        label: &'static str,
        init: Init,
    },
    Dispatch {
        stage: &'static StageDef,
        constants: Vec<(&'static str, f64)>,
        workgroups: [u32; 3],
        bindings: Vec<BufProxy>,
    },
    Download(BufProxy),
}

enum Init {
    Data(Vec<u32>),
    /// Every word set to this pattern, so an output the pass never wrote stands out.
    Fill(u32),
}

/// Uploads, dispatches and downloads, to be run by an [`Engine`].
#[derive(Default)]
pub struct Recording {
    cmds: Vec<Cmd>,
    n_bufs: usize,
}

fn to_words(bytes: &[u8]) -> Vec<u32> {
    let mut words = vec![0u32; bytes.len().div_ceil(4)];
    bytemuck::cast_slice_mut::<u32, u8>(&mut words)[..bytes.len()].copy_from_slice(bytes);
    words
}

impl Recording {
    fn new_buf(&mut self, size: u64) -> BufProxy {
        let buf = BufProxy {
            id: self.n_bufs,
            size: size.max(4).next_multiple_of(4),
        };
        self.n_bufs += 1;
        buf
    }

    /// A buffer initialised with `data`.
    pub fn upload<T: bytemuck::Pod>(&mut self, label: &'static str, data: &[T]) -> BufProxy {
        let words = to_words(bytemuck::cast_slice(data));
        let buf = self.new_buf(words.len() as u64 * 4);
        self.cmds.push(Cmd::Create {
            buf,
            label,
            init: Init::Data(words),
        });
        buf
    }

    /// A uniform buffer laid out by encase (WGSL uniform rules, no hidden padding).
    pub fn uniform<T: encase::ShaderType + encase::internal::WriteInto>(
        &mut self,
        label: &'static str,
        value: &T,
    ) -> BufProxy {
        let mut ub = encase::UniformBuffer::new(Vec::<u8>::new());
        ub.write(value).expect("uniform fits in memory");
        let words = to_words(&ub.into_inner());
        let buf = self.new_buf(words.len() as u64 * 4);
        self.cmds.push(Cmd::Create {
            buf,
            label,
            init: Init::Data(words),
        });
        buf
    }

    /// A buffer of `size` bytes with every 32-bit word set to `fill`.
    pub fn alloc(&mut self, label: &'static str, size: u64, fill: u32) -> BufProxy {
        let buf = self.new_buf(size);
        self.cmds.push(Cmd::Create {
            buf,
            label,
            init: Init::Fill(fill),
        });
        buf
    }

    /// Runs `stage` over `workgroups` with `bindings` in binding order. `constants` set the
    /// WGSL `override` values; the CPU mirror reads the same values from its uniforms.
    pub fn dispatch(
        &mut self,
        stage: &'static StageDef,
        workgroups: [u32; 3],
        bindings: &[BufProxy],
        constants: &[(&'static str, f64)],
    ) {
        assert_eq!(
            bindings.len(),
            stage.bindings.len(),
            "stage {} takes {} bindings",
            stage.name,
            stage.bindings.len()
        );
        self.cmds.push(Cmd::Dispatch {
            stage,
            constants: constants.to_vec(),
            workgroups,
            bindings: bindings.to_vec(),
        });
    }

    /// Asks for `buf` to be read back after the run.
    pub fn download(&mut self, buf: BufProxy) {
        self.cmds.push(Cmd::Download(buf));
    }
}

/// Buffers read back from a run.
pub struct Downloads {
    bufs: HashMap<usize, Vec<u32>>,
}

impl Downloads {
    pub fn get<T: bytemuck::Pod>(&self, buf: BufProxy) -> Vec<T> {
        let words = self
            .bufs
            .get(&buf.id)
            .expect("buffer was recorded for download");
        bytemuck::cast_slice(words).to_vec()
    }
}

/// Workgroups needed to cover `n` items with groups of `size`.
pub fn groups(n: u32, size: u32) -> u32 {
    n.div_ceil(size).max(1)
}

type PipelineKey = (&'static str, Vec<(&'static str, u64)>);

/// Runs recordings on the GPU or on the CPU mirrors.
pub struct Engine {
    gpu: Option<GpuContext>,
    pipelines: Mutex<HashMap<PipelineKey, wgpu::ComputePipeline>>,
    /// Largest single buffer a stage may bind; hosts tile work to stay under it.
    max_binding: u64,
    /// Memory the jobs run on this engine may use; checked before work starts.
    budget: crate::base::budget::Budget,
}

/// The CPU backend has no binding limit of its own; tiles this size keep memory bounded.
const CPU_MAX_BINDING: u64 = 1 << 30;

impl Engine {
    /// An engine for the requested backend. `auto` takes a hardware GPU if one exists and the
    /// CPU mirrors otherwise (lavapipe is only used when `gpu` is asked for).
    pub fn new(choice: BackendChoice) -> Result<Self> {
        let gpu = match choice {
            BackendChoice::Cpu => None,
            BackendChoice::Gpu => Some(GpuContext::new()?),
            BackendChoice::Auto => {
                if crate::gpu::hardware_gpu_present() {
                    Some(GpuContext::new()?)
                } else {
                    None
                }
            }
        };
        let max_binding = gpu
            .as_ref()
            .map_or(CPU_MAX_BINDING, |g| g.max_binding_bytes());
        Ok(Engine {
            gpu,
            pipelines: Mutex::new(HashMap::new()),
            max_binding,
            budget: crate::base::budget::Budget::machine(),
        })
    }

    pub fn cpu() -> Self {
        Engine::new(BackendChoice::Cpu).expect("the CPU backend always opens")
    }

    pub fn is_gpu(&self) -> bool {
        self.gpu.is_some()
    }

    pub fn gpu(&self) -> Option<&GpuContext> {
        self.gpu.as_ref()
    }

    /// "gpu: <adapter>" or "cpu (N threads)".
    pub fn describe(&self) -> String {
        match &self.gpu {
            Some(g) => format!("gpu: {}", crate::gpu::describe(&g.info)),
            None => format!("cpu ({} threads)", rayon::current_num_threads()),
        }
    }

    pub fn max_binding_bytes(&self) -> u64 {
        self.max_binding
    }

    /// Lowers the binding limit, to exercise tiling in tests or to bound memory.
    pub fn set_max_binding_bytes(&mut self, bytes: u64) {
        self.max_binding = self.max_binding.min(bytes);
    }

    pub fn budget(&self) -> &crate::base::budget::Budget {
        &self.budget
    }

    /// Sets the memory budget (`--max-memory`); the default is the machine's.
    pub fn set_budget(&mut self, budget: crate::base::budget::Budget) {
        self.budget = budget;
    }

    /// Runs every command of `rec` in order and returns the requested downloads.
    pub fn run(&self, rec: Recording) -> Result<Downloads> {
        for cmd in &rec.cmds {
            if let Cmd::Create { buf, label, .. } = cmd {
                if buf.size > self.max_binding {
                    return Err(Error::TooLarge {
                        what: format!("buffer {label}"),
                        needed: buf.size,
                        limit: self.max_binding,
                        limit_name: "largest buffer binding".into(),
                        unit: "bytes",
                    });
                }
            }
        }
        match &self.gpu {
            Some(g) => self.run_gpu(g, rec),
            None => Ok(run_cpu(rec)),
        }
    }

    fn pipeline(
        &self,
        g: &GpuContext,
        stage: &'static StageDef,
        constants: &[(&'static str, f64)],
    ) -> Result<wgpu::ComputePipeline> {
        let key: PipelineKey = (
            stage.name,
            constants.iter().map(|(k, v)| (*k, v.to_bits())).collect(),
        );
        let mut cache = self.pipelines.lock().unwrap();
        if let Some(p) = cache.get(&key) {
            return Ok(p.clone());
        }
        let source = crate::gpu::wgsl::compose(stage.name, stage.wgsl)?;
        let pipeline = {
            let module = g.device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(stage.name),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
            let entries: Vec<wgpu::BindGroupLayoutEntry> = stage
                .bindings
                .iter()
                .enumerate()
                .map(|(i, b)| wgpu::BindGroupLayoutEntry {
                    binding: i as u32,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: match b {
                            Bind::Uniform => wgpu::BufferBindingType::Uniform,
                            Bind::Read => wgpu::BufferBindingType::Storage { read_only: true },
                            Bind::ReadWrite => {
                                wgpu::BufferBindingType::Storage { read_only: false }
                            }
                        },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                })
                .collect();
            let bgl = g
                .device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some(stage.name),
                    entries: &entries,
                });
            let layout = g
                .device
                .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some(stage.name),
                    bind_group_layouts: &[Some(&bgl)],
                    immediate_size: 0,
                });
            g.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(stage.name),
                    layout: Some(&layout),
                    module: &module,
                    entry_point: Some("main"),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants,
                        zero_initialize_workgroup_memory: true,
                    },
                    cache: None,
                })
        };
        cache.insert(key, pipeline.clone());
        Ok(pipeline)
    }

    fn run_gpu(&self, g: &GpuContext, rec: Recording) -> Result<Downloads> {
        let scope = g.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let oom = g.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let mut buffers: HashMap<usize, wgpu::Buffer> = HashMap::new();
        let mut encoder = g
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("coif"),
            });
        let mut staging: Vec<(usize, wgpu::Buffer)> = Vec::new();
        let passes = rec
            .cmds
            .iter()
            .filter(|c| matches!(c, Cmd::Dispatch { .. }))
            .count();
        let mut queries = crate::gpu::timer::PassQueries::new(g, passes);
        for cmd in rec.cmds {
            match cmd {
                Cmd::Create { buf, label, init } => {
                    let mut usage = wgpu::BufferUsages::STORAGE
                        | wgpu::BufferUsages::COPY_SRC
                        | wgpu::BufferUsages::COPY_DST;
                    if buf.size <= g.limits.max_uniform_buffer_binding_size {
                        usage |= wgpu::BufferUsages::UNIFORM;
                    }
                    let b = g.device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some(label),
                        size: buf.size,
                        usage,
                        mapped_at_creation: true,
                    });
                    {
                        let mut view = b
                            .get_mapped_range_mut(..)
                            .map_err(|e| Error::Gpu(format!("cannot map buffer {label}: {e}")))?;
                        // Mapped memory is write-only in wgpu 30: copy whole words in.
                        let words = match init {
                            Init::Data(d) => d,
                            Init::Fill(v) => vec![v; (buf.size / 4) as usize],
                        };
                        view.copy_from_slice(bytemuck::cast_slice(&words));
                    }
                    b.unmap();
                    buffers.insert(buf.id, b);
                }
                Cmd::Dispatch {
                    stage,
                    constants,
                    workgroups,
                    bindings,
                } => {
                    let pipeline = self.pipeline(g, stage, &constants)?;
                    let entries: Vec<wgpu::BindGroupEntry> = bindings
                        .iter()
                        .enumerate()
                        .map(|(i, b)| wgpu::BindGroupEntry {
                            binding: i as u32,
                            resource: buffers[&b.id].as_entire_binding(),
                        })
                        .collect();
                    let bg = g.device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some(stage.name),
                        layout: &pipeline.get_bind_group_layout(0),
                        entries: &entries,
                    });
                    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some(stage.name),
                        timestamp_writes: queries.as_mut().map(|q| q.compute(stage.name)),
                    });
                    pass.set_pipeline(&pipeline);
                    pass.set_bind_group(0, &bg, &[]);
                    pass.dispatch_workgroups(workgroups[0], workgroups[1], workgroups[2]);
                }
                Cmd::Download(buf) => {
                    let st = g.device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("coif.staging"),
                        size: buf.size,
                        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                        mapped_at_creation: false,
                    });
                    encoder.copy_buffer_to_buffer(&buffers[&buf.id], 0, &st, 0, buf.size);
                    staging.push((buf.id, st));
                }
            }
        }
        if let Some(q) = &mut queries {
            q.resolve(g, &mut encoder);
        }
        g.queue.submit([encoder.finish()]);
        for (_, st) in &staging {
            st.slice(..).map_async(wgpu::MapMode::Read, |_| {});
        }
        if let Some(q) = &queries {
            q.map();
        }
        g.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Gpu(format!("device poll failed: {e}")))?;
        if let Some(e) = pollster::block_on(oom.pop()) {
            return Err(Error::Gpu(e.to_string()));
        }
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(Error::Gpu(e.to_string()));
        }
        g.check_errors()?;
        if let Some(q) = queries {
            q.finish(g)?;
        }
        let mut out = HashMap::new();
        for (id, st) in staging {
            let view = st
                .slice(..)
                .get_mapped_range()
                .map_err(|e| Error::Gpu(format!("cannot map a read-back buffer: {e}")))?;
            out.insert(id, bytemuck::cast_slice(&view[..]).to_vec());
        }
        Ok(Downloads { bufs: out })
    }
}

fn run_cpu(rec: Recording) -> Downloads {
    let mut bufs: HashMap<usize, RefCell<Vec<u32>>> = HashMap::new();
    let mut out = HashMap::new();
    for cmd in rec.cmds {
        match cmd {
            Cmd::Create { buf, init, .. } => {
                let words = match init {
                    Init::Data(d) => d,
                    Init::Fill(v) => vec![v; (buf.size / 4) as usize],
                };
                bufs.insert(buf.id, RefCell::new(words));
            }
            Cmd::Dispatch {
                stage,
                workgroups,
                bindings,
                ..
            } => {
                let cb: Vec<CpuBinding> = bindings
                    .iter()
                    .map(|b| CpuBinding { data: &bufs[&b.id] })
                    .collect();
                (stage.cpu)(workgroups, &cb);
            }
            Cmd::Download(buf) => {
                out.insert(buf.id, bufs[&buf.id].borrow().clone());
            }
        }
    }
    Downloads { bufs: out }
}
